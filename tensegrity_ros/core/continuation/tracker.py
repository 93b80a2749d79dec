"""The jump-aware tracker: the follower, with what happens where its steps are rejected.

An event exists only between two verified states where a test function changes sign
(:mod:`.indicators`); it is located (:mod:`.locator`) and the mechanism lands
(:mod:`.lander`), or, at a supercritical branch point, follows the buckled minimum
(:mod:`.branch_switching`).  At a linkage limit the constraint's own events decide
(:mod:`.linkage_limits`).  :func:`track`, :func:`track_settled` and :func:`settle` are
the entry points; :class:`.results.Track` the result.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import branch_switching, certificates, lander, linkage_limits, locator
from .flows import slide
from .follower import Follower, Move, out_of_budget, Stop
from .problem import PathProblem
from .results import Track, TrackingError
from .run_state import RunState
from .settings import LOCATION_TOL, TrackerSettings
from ..numerics.bounded_work import Budget
from ..numerics.tolerances import BRANCH_POINT_CERTIFIED


class Events:
    """What the tracker does where a step is rejected (the follower's ``events``): each
    method takes the run (so one instance serves every run)."""

    def before_arc(self, run, rejected):
        """Before an arclength step: a command ending by a branch point's normal form,
        leaving a branch point it starts on, or lambda_min's crossing on the natural
        path.  A :class:`Move`, a :class:`Stop`, ('found', critical point) or None."""
        y, s, s_end = rejected.y, rejected.s, rejected.s_end
        ended = branch_switching.toward_branch_point(run, y, s, s_end)   # certified y only
        if ended is not None:
            return Move(*ended, restart=False, rescale=False)
        if rejected.reason != 'indefinite':
            return None
        if run.certificate == BRANCH_POINT_CERTIFIED:
            # at the branch point itself, the command leading into its buckling side
            moved = branch_switching.leave_branch_point(run, y, s, s_end)
            if moved is None:
                return Stop(f'no stable buckled state found leaving the branch point at '
                            f's={s!r}')
            return Move(moved[0], moved[1])
        found = locator.crossing_on_path(run, y, s, rejected.tangent, s + rejected.ds)
        if ((found is None or found[1] > s_end)
                and certificates.on_linear_law(run, rejected.eigenvalues,
                                               rejected.end_eigenvalues, rejected.rate,
                                               rejected.ds)):
            # lambda_min falls linearly to a branch point the command runs through, and
            # no crossing is found on the path: the buckled branch ends there (a verified
            # state not yet certified, e.g. the module 1e-9 .. 5e-10 in rho past rho = L
            # going back up)
            ended = branch_switching.toward_branch_point(run, y, s, s_end, near=True)
            if ended is not None:
                return Move(*ended, rescale=False)
        return None if found is None else ('found', found)

    def locate_on_arc(self, run, y, s, direction, h, definite_at_end):
        """The critical point on an arclength step (see :func:`.locator.crossing_on_arc`)."""
        return locator.crossing_on_arc(run, y, s, direction, h, definite_at_end)

    def of_this_branch(self, run, rejected, found):
        """Whether a located critical point belongs to the branch followed: it lies
        ahead of the state it was located from (to the location tolerance), or its
        critical state is within the passage radius of it (a state the normal form carried
        a little past it: an imperfect C1, L2 = 1 + 1e-7, test_tracking_imperfect).  One
        behind and apart lies on another branch an arclength corrector reached: the module
        under a symmetric 1e-6 N load just past its imperfect pitchfork, where its branch
        bends on a scale of 1e-5 in s, crossed to the lost branch and found its fold,
        1.8e-3 rad away and behind, again and again (test_decided_paths); a neck's start
        within rounding of a fold put a 'branch point' 6.2e-4 in s before the command on
        some BLAS kernels and went on silently (H30: test_neck_jump_off_a_mirror_
        symmetric_state_says_its_mirror_image_lands_as_well)."""
        return (found[1] >= rejected.s - LOCATION_TOL
                or run.separation(found[2], rejected.y) <= run.settings.passage_radius)

    def after_arc(self, run, rejected, found):
        """At a located critical point: land (or cross the linkage limit it is); where
        steps underflow: the linkage limit's events, a critical point reached to
        rounding.  A :class:`Move`, a :class:`Stop`, or None (a shorter step)."""
        s_end = rejected.s_end
        if found is not None and not self.of_this_branch(run, rejected, found):
            found = None
        if found is not None and found[1] <= s_end:
            if run.stop_at_events:
                run.stopped_at_event = found[1]
                return Stop(f'a critical point at s={found[1]!r} (not landed: stop_at_events)')
            # at a linkage limit the flow of land() stalls: cross it first
            moved = linkage_limits.through_linkage_limit(run, found[2], found[1], s_end)
            try:
                moved = moved or lander.land(run, *found, s_end)
            except TrackingError as error:
                return Stop(str(error))
        elif rejected.ds <= run.settings.min_step:
            y, s = rejected.y, rejected.s
            moved = (linkage_limits.through_linkage_limit(run, y, s, s_end)
                     or lander.end_at_rounding(run, y, s, s_end)
                     or linkage_limits.leave_crossing(run, y, s, s_end))
            if moved is None:
                return Stop(linkage_limits.underflow_reason(run, y, s, rejected.reason))
        else:
            return None
        y1, s1, event = moved
        return Move(y1, s1, event, new_branch=True)


EVENTS = Events()


class Tracker:
    """One tracking run of ``problem``: its :class:`.run_state.RunState` and follower."""

    def __init__(self, problem, settings):
        self.state = RunState(problem, settings, Tracker)
        self.follower = Follower(self.state, EVENTS)

    def run(self, y, s_end=1.0, certificate=''):
        """Follow the stable branch from (y, 0) to s_end, jumping where it must."""
        return self.follower.follow(y, s_end, certificate)


def track(problem: PathProblem, y0, settings: TrackerSettings = TrackerSettings(),
          certificate='') -> Track:
    """Follow the stable equilibrium at ``y0`` (s = 0) to s = 1, jumping where it must.

    Raises :class:`TrackingError` if ``y0`` is not (close to) a stable
    equilibrium at s = 0; every other outcome is reported in the result.
    ``certificate``: the :attr:`Track.certificate` ``y0`` was verified with, if any.
    Where ``settings.time_budget`` runs out, the result is the last verified state
    (status 'failed', the reason in ``message``).
    """
    tracker = Tracker(problem, settings)
    y0 = np.array(y0, dtype=float)
    if settings.time_budget is None:    # (the Budget's with-block costs ~0.6 us)
        return tracker.run(y0, certificate=certificate)
    with Budget(settings.time_budget, settings.clock):
        return tracker.run(y0, certificate=certificate)
    return out_of_budget(tracker.state)     # reached only where the budget ran out


def track_settled(problem: PathProblem, y0, settings: TrackerSettings = TrackerSettings(),
                  certificate='') -> Track:
    """:func:`track` from ``y0``, or, where ``y0`` is not a stable equilibrium at s = 0,
    from where the mechanism released there settles (:func:`settle`, from ``y0``
    projected); the settling and the tracking share one ``settings.time_budget``."""
    started = None if settings.time_budget is None else settings.clock()

    def left():
        """``settings`` with what is left of the time budget."""
        if started is None:
            return settings
        spent = settings.clock() - started
        return replace(settings, time_budget=max(settings.time_budget - spent, 0.0))

    try:
        return track(problem, y0, settings, certificate)
    except TrackingError:
        pass
    y0 = settle(problem, problem.project(np.array(y0, dtype=float), 0.0), 0.0, left())
    return track(problem, y0, left())


def settle(problem: PathProblem, y0, s=0.0, settings: TrackerSettings = TrackerSettings()):
    """Where the overdamped mechanism released at ``y0`` comes to rest (at fixed s).

    Returns the verified stable state, or raises :class:`TrackingError`.  A start
    on a saddle's stable set is pushed off along the unstable mode (both ways;
    the lower-energy landing wins) so that the answer is always a minimum.
    ``settings.time_budget`` bounds it too (running out raises TrackingError).
    """
    with Budget(settings.time_budget, settings.clock):
        return _settle(problem, np.array(y0, dtype=float), s, settings)
    raise TrackingError(f'time budget of {settings.time_budget:g} s used up before the '
                        f'mechanism came to rest')


def _settle(problem, y0, s, settings):
    """:func:`settle` without its time budget."""
    run = Tracker(problem, settings).state
    eigenvalues, modes = problem.stability(y0, s)
    run.scale = max(float(np.max(np.abs(eigenvalues))), 1e-300)   # any start, not only a minimum
    y = run.newton(y0, s) if run.residual_ok(y0, s) else None
    if y is None or run.definite(run.eigenvalues(y, s)):
        landing = slide(run, y0, s)        # not on a saddle: the flow decides alone
        if landing is not None:
            return landing
    candidates = []
    for sign in (1.0, -1.0):
        start = y0 if y is None else y
        eig, modes = problem.stability(start, s)
        candidate = slide(
            run, problem.project(start + sign * run.step_off_vector(modes[:, 0]), s), s)
        if candidate is not None:
            candidates.append(candidate)
    if not candidates:
        raise TrackingError('no stable equilibrium reached from the given state')
    return min(candidates, key=lambda v: problem.energy(v, s))
