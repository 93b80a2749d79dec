"""Follow a stable equilibrium along a parameter path, with jump detection (docs/model.md,
section 3).

The tracker knows nothing about tensegrity: it works on a :class:`PathProblem`, a
family of equilibrium equations ``F(y, s) = 0`` along a path ``s in [0, 1]`` with an
energy and a stability matrix.  One module (2 angles) and the neck stack (angles and
Lagrange multipliers) both implement it, and run through the same code.

The concepts, each in its own module (docs/architecture.md draws the arrows):

* :mod:`.problem`, :mod:`.settings`, :mod:`.results`: the problem, the tolerances and
  the results, as plain data;
* :mod:`.run_state`: one run's state and the verified-state primitives (Newton,
  eigenvalues, the margin test, norms); :mod:`.step_rules`: a step's acceptance rules;
* :mod:`.correctors`: the branch as a curve (tangent, pseudo-arclength corrector);
* :mod:`.follower`: the path follower (natural and arclength steps, step control);
  it knows nothing of jumps;
* :mod:`.certificates`: minima below the margin test, shown by a branch point's
  normal form;
* :mod:`.indicators` and :mod:`.locator`: test functions evaluated on the branch and
  the location of their sign changes;
* :mod:`.branch_switching`: supercritical branch points (the minimum buckles: no jump);
* :mod:`.flows` and :mod:`.lander`: where a lost minimum goes (gradient flows at frozen
  parameters); :mod:`.ambiguity`: when rounding chose the landing;
* :mod:`.linkage_limits`: constraints whose gradient vanishes, with their own events;
* :mod:`.tracker`: the follower plus the events policy; :func:`track`,
  :func:`track_settled`, :func:`settle`.
"""
from .problem import PathProblem
from .results import (BRANCH_POINT, Event, FOLD, PITCHFORK_CERTIFIED, Track, TrackingError,
                      Undecided)
from .settings import (ARC_RESOLUTION, LOCATION_TOL, PITCHFORK_CONTRACTION, TrackerSettings,
                       UNRESOLVED, UNRESOLVED_UPDATE)
from .step_rules import (energy_consistent, forward_rate, near_prediction, on_one_branch,
                         positive_definite, step_bound)
from .tracker import settle, track, track_settled

__all__ = [
    'PathProblem', 'TrackerSettings', 'Track', 'Event', 'TrackingError', 'Undecided', 'FOLD',
    'BRANCH_POINT', 'PITCHFORK_CERTIFIED', 'PITCHFORK_CONTRACTION', 'LOCATION_TOL',
    'UNRESOLVED', 'UNRESOLVED_UPDATE', 'ARC_RESOLUTION', 'track', 'track_settled', 'settle',
    'positive_definite', 'step_bound', 'forward_rate', 'near_prediction',
    'energy_consistent', 'on_one_branch',
]
