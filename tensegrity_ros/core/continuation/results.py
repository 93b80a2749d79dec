"""What tracking returns, as plain data: the jumps (:class:`Event`) and the run
(:class:`Track`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FOLD = 'fold'
BRANCH_POINT = 'branch_point'
#: A final state certified by a passed pitchfork's normal form (see
#: :func:`.branch_switching.buckled_at`).
PITCHFORK_CERTIFIED = 'pitchfork_normal_form'


@dataclass(frozen=True)
class Event:
    """A jump: the stable branch ended (``fold``) or lost stability (``branch_point``) at ``s``.

    ``landing`` is a verified stable equilibrium at ``landing_s``, which is ``s`` unless
    that minimum does not exist back at ``s`` (see :func:`.lander.landing_at_event`)."""

    kind: str
    s: float
    state: np.ndarray
    landing_s: float
    landing: np.ndarray
    ambiguous: bool = False


@dataclass(frozen=True)
class Undecided:
    """A supercritical branch point passed whose side doubles cannot decide: the law of
    its branch (:func:`.normal_form.branch_law`) held down to amplitude ``amplitude`` (in
    the tracker's state norm) and s - s* = ``s_uncertainty``; an imperfection whose
    branch structure lies below that would pick the side the mechanism takes, and the
    tracker took one by its rule (:func:`.branch_switching.buckled_minimum`).  Not a
    jump: the passage is listed too."""

    s: float
    state: np.ndarray
    s_uncertainty: float
    amplitude: float


@dataclass(frozen=True)
class Track:
    """Result of :func:`track`: the last verified stable state, where it is, and the events.

    ``status`` is ``'ok'`` when ``s == 1``, else ``'failed'`` with a ``message``;
    ``state`` has always passed the residual and positive-definiteness checks.
    ``passages``: (s, critical state) of each supercritical branch point the state
    passed continuously (it buckled smoothly onto a new minimum: not a jump, no event).
    ``certificate`` says how ``state`` was shown positive definite: ``''`` by the margin
    test (lambda_min > definiteness_tol * lambda_max), or :data:`PITCHFORK_CERTIFIED`:
    the command ended so close past a passed branch point (~1e-6 in s) that the
    buckled minimum's lambda_min is below that margin, and it is shown positive by the
    branch point's normal form instead (:func:`.branch_switching.buckled_at`).
    ``undecided``: the passages whose side doubles could not decide (:class:`Undecided`).
    """

    state: np.ndarray
    s: float
    eigenvalues: np.ndarray
    events: tuple = ()
    status: str = 'ok'
    message: str = ''
    steps: int = 0
    passages: tuple = ()
    certificate: str = ''
    undecided: tuple = ()


class TrackingError(RuntimeError):
    """The start state is not a stable equilibrium and cannot be made one."""
