"""What a simulator call did: an :class:`Outcome` with a status, and the events on the way.

Modelled on scipy's result objects (``OptimizeResult``, ``RootResults``): a call never
raises for input a user could send (a NaN, an out-of-range target); it answers with
``status`` and a reason.  The events are plain records the caller (the node, a test,
a script) turns into messages, logs or counts.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Outcome statuses.
OK = 'ok'               # accepted; every path tracked to its end (or nothing to do)
FAILED = 'failed'       # accepted; a path stopped early: the state is the last verified one
REFUSED = 'refused'     # bad input: nothing changed; ``reason`` and ``message`` say why

#: Refusal reasons (the node counts them as ``rejected_<reason>``).
NON_FINITE = 'non_finite'
OUT_OF_RANGE = 'out_of_range'
PARAMETER_VALUE = 'parameter_value'


@dataclass(frozen=True)
class Jump:
    """The mechanism jumped: its branch ended (``fold``) or lost stability (``branch_point``).

    ``modules`` are every module's parameters at the critical point (``modules[i].rho`` is
    module i's critical actuator length); ``from_theta`` (N x 2) the critical configuration,
    ``to_theta`` (N x 2) where it landed.  ``module`` is the module whose command moved
    the mechanism there, ``cause`` names the command, ``count`` is the running jump number
    since the start or the last reset.  ``dynamics`` (dynamics mode only, else None): the
    snap's figures once the rods came to rest
    (:class:`~.simulation.dynamic_simulator.DynamicSimulator`).
    """

    kind: str
    s: float
    modules: tuple
    from_theta: np.ndarray
    to_theta: np.ndarray
    ambiguous: bool
    module: int
    cause: str
    count: int
    dynamics: dict | None = None
    #: The parameters ``to_theta`` is an equilibrium of: ``modules`` (None: the same) except
    #: where the landing minimum exists only a little past the critical point (a neck's
    #: fold: e.g. 5e-5 m further), or, in dynamics mode, those where the rods came to rest.
    landing_modules: tuple | None = None

    @property
    def landing(self):
        """The parameters ``to_theta`` is an equilibrium of (see ``landing_modules``)."""
        return self.modules if self.landing_modules is None else self.landing_modules


@dataclass(frozen=True)
class Passage:
    """Not a jump: the mechanism passed a supercritical branch point continuously (its
    minimum buckled smoothly onto one of two new minima, e.g. a neck bending sideways).
    ``modules`` are every module's parameters there; ``module`` and ``cause`` as in
    :class:`Jump`.  Worth a log line: the state left a symmetric branch for one side."""

    modules: tuple
    module: int
    cause: str


@dataclass(frozen=True)
class Undecided:
    """Not a jump, and not decided: the mechanism passed a branch point continuously
    (listed as a :class:`Passage` too), but which side it buckled to lies below what
    doubles resolve.  An imperfection whose branch structure spans less than
    ``s_uncertainty`` of the command's path (``rho_uncertainty[i]`` m of module i's
    actuator; 0 where the command does not move it, e.g. a load) would pick the side (a
    perfectly symmetric model has none); the simulator took one by the tracker's rule.
    ``modules``
    are every module's parameters there, ``theta`` (N x 2) the critical configuration;
    ``module`` and ``cause`` as in :class:`Jump`."""

    modules: tuple
    theta: np.ndarray
    s_uncertainty: float
    rho_uncertainty: tuple
    module: int
    cause: str


def passage_events(motion, module, cause):
    """The :class:`Passage` and :class:`Undecided` events of a tracked ``motion``
    (:class:`~.simulation.mechanisms.Motion`), made by ``module``'s command ``cause``."""
    passages = tuple(Passage(modules=tuple(modules), module=module, cause=cause)
                     for modules in motion.passages)
    return passages + tuple(Undecided(tuple(modules), theta, s_size, tuple(span), module, cause)
                            for modules, theta, s_size, span in motion.undecided)


@dataclass(frozen=True)
class TrackingFailure:
    """A path could not be tracked to its end; ``text`` says where and why.  The state
    is the last verified one (where tracking stopped, or unchanged)."""

    module: int
    text: str


@dataclass(frozen=True)
class Deferred:
    """A path of ``module``'s command ``cause`` needs more than one call's time budget:
    it goes on in the following calls (``text`` says so); until it ends the state is the
    last verified one.  Reported once per path."""

    module: int
    cause: str
    text: str


@dataclass(frozen=True)
class BranchEnd:
    """Where a neck's live branch ends on the path ahead of a speed-limited actuator,
    found by tracking that path in advance: ``rho`` is the commanded module's actuator
    length there, ``kind`` ``fold`` or ``branch_point``, ``modules`` every module's
    parameters and ``theta`` (N x 2) the critical configuration."""

    rho: float
    kind: str
    modules: tuple
    theta: np.ndarray


@dataclass(frozen=True)
class JumpAhead:
    """Early warning: the target ``rho`` of ``module`` lies beyond the end of the live
    branch (``end``: one module's exact operation-range end, a neck's :class:`BranchEnd`;
    either has ``rho`` and ``kind``, a fold or branch point): the mechanism will jump."""

    module: int
    rho: float
    end: object
    cause: str


@dataclass(frozen=True)
class Outcome:
    """Result of one simulator call: ``status`` (``ok``, ``failed`` or ``refused``), for a
    refusal its ``reason`` and ``message``, and the ``events`` (jumps, failures, warnings)
    in the order they happened."""

    status: str = OK
    events: tuple = ()
    reason: str = ''
    message: str = ''

    @property
    def accepted(self):
        return self.status != REFUSED

    def of_type(self, kind):
        """The events that are instances of ``kind``."""
        return [e for e in self.events if isinstance(e, kind)]


def refused(reason, message):
    return Outcome(status=REFUSED, reason=reason, message=message)


def combined(outcomes):
    """One outcome for several accepted steps: failed if any failed, every event in order."""
    if type(outcomes) is list and len(outcomes) == 1:   # a command's path: already one
        only = outcomes[0]
        if only.status != REFUSED and not (only.reason or only.message):
            return only
    events = tuple(e for o in outcomes for e in o.events)
    failed = any(o.status == FAILED for o in outcomes)
    return Outcome(status=FAILED if failed else OK, events=events)
