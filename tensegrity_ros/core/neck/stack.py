"""The neck stack: N modules with coupled statics (docs/model.md section 4), tracked.

The model is :mod:`.neck.model` (parameters, node graph, evaluation) and
:class:`.neck.path.StackPath` (a path of stacks as the tracker's problem); here are the
verified records, the tracker's entry points for a neck and a multi-start search.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math

import numpy as np
from scipy.optimize import root

from .fast_step import keep_final_point, whole_command_step
from .model import Stack
from .path import StackPath
from .. import continuation as _continuation
from ..continuation import TrackerSettings
from ..numerics.tolerances import verified_minimum

__all__ = ['Stack', 'StackPath', 'StackEquilibrium', 'StackJump', 'StackPassage', 'StackTrack',
           'StackUndecided', 'stack_equilibrium_at', 'settle_stack', 'track_stack',
           'stack_equilibria']


@dataclass(frozen=True)
class StackEquilibrium:
    """A verified equilibrium of a stack.

    ``theta`` (N x 2) local angles, ``nodes`` (2 + 2N, 2) every node in the base frame
    (A1(0), A2(0), then A3(i), A4(i) for each module), ``eigenvalues`` of the reduced
    Hessian (N/m, ascending), ``actuator_forces`` (N,), ``state`` the tracker state,
    ``head_position`` (2,) and ``head_angle`` the midpoint and direction of the top chord.
    The angles, forces, nodes and head are made on first use, from ``evaluation``: a
    node tracks a state per command (1 kHz) but reads them only at publish_rate.
    ``certificate`` is the tracker's (:attr:`.continuation.Track.certificate`): non-empty
    where the state is so close past a passed branch point that its positive
    definiteness was shown by the branch point's normal form, not by the margin test
    (``stable`` accepts either).
    """

    eigenvalues: np.ndarray
    energy: float
    residual: float
    state: np.ndarray
    #: The stack parameter vector (bytes) this state was verified at, so that tracking
    #: from it can reuse ``eigenvalues``.
    parameters: bytes = field(default=None, repr=False, compare=False)
    #: (path, point): the path's evaluation at ``state``, that the lazy values come from.
    evaluation: tuple = field(default=None, repr=False, compare=False)
    certificate: str = ''

    @functools.cached_property
    def theta(self):
        path, point = self.evaluation
        return path.angles_at(point)

    @functools.cached_property
    def actuator_forces(self):
        path, point = self.evaluation
        return path.actuator_forces_at(point)

    @functools.cached_property
    def nodes(self):
        path, point = self.evaluation
        return path.nodes_at(point)

    @property
    def head_position(self):
        (x3, y3), (x4, y4) = self.nodes[-2:].tolist()   # the top chord: A3(N-1), A4(N-1)
        return np.array([0.5 * (x3 + x4), 0.5 * (y3 + y4)])

    @property
    def head_angle(self):
        (x3, y3), (x4, y4) = self.nodes[-2:].tolist()
        return math.atan2(y3 - y4, x3 - x4)

    @property
    def stable(self):
        ev = self.eigenvalues
        return verified_minimum(ev, self.certificate)

    @property
    def stability_margin(self):
        return float(self.eigenvalues[0])


def _record(path, y, s, eigenvalues=None, energy=None, residual=None, certificate=''):
    y = path.whole_turns_removed(y)
    p = path.point(y, s)
    return StackEquilibrium(
        eigenvalues=path.eigenvalues_at(p) if eigenvalues is None else eigenvalues,
        energy=path.energy_at(p) if energy is None else energy,
        residual=float(np.max(np.abs(path.residual_at(p)))) if residual is None else residual,
        state=np.array(y), parameters=path.parameter_bytes(s), evaluation=(path, p),
        certificate=certificate)


def _end_record(path, y, eigenvalues, energy, residual, point):
    """The record of the small-command step's verified end: ``point`` is its evaluation
    at ``y``, s = 1, and ``y`` the step's own array (held by the point alone, so the
    record takes it without a copy).

    Made by filling the instance dict: the frozen dataclass's __init__ sets each of its
    seven fields through object.__setattr__ (2.7 us, against 0.7 here, on a ~95 us
    command); the same instance, as StackEquilibrium has no __post_init__ (a field added
    to it must be added here too)."""
    record = object.__new__(StackEquilibrium)
    record.__dict__.update(eigenvalues=eigenvalues, energy=energy, residual=residual,
                           state=y, parameters=path.end._bytes, evaluation=(path, point),
                           certificate='')
    return record


def stack_equilibrium_at(stack: Stack, state) -> StackEquilibrium:
    """The record of a tracker state of ``stack``."""
    return _record(StackPath(stack, stack), np.asarray(state, dtype=float), 0.0)


@dataclass(frozen=True)
class StackJump:
    """A jump of the stack: ``theta`` of every module before (critical) and after (landing).

    ``to_theta`` is a stable equilibrium of ``stack`` (the parameters at the jump's s),
    except where the landing minimum does not exist there (it appears only past s): then
    ``landing_stack`` (otherwise ``stack``) holds the parameters it is an equilibrium of,
    and ``landed_past`` is true."""

    kind: str
    s: float
    stack: Stack
    from_theta: np.ndarray
    to_theta: np.ndarray
    ambiguous: bool = False
    landing_stack: Stack | None = None

    @property
    def landed_past(self):
        return self.landing_stack is not None and self.landing_stack != self.stack


@dataclass(frozen=True)
class StackPassage:
    """A supercritical branch point the stack passed continuously (it buckled smoothly:
    not a jump).  ``theta`` is the critical state (every module's angles)."""

    s: float
    stack: Stack
    theta: np.ndarray


@dataclass(frozen=True)
class StackUndecided:
    """A passage whose side doubles cannot decide (see :class:`.module.tracking.ModuleUndecided`):
    ``rho_uncertainty`` holds every module's actuator span over ``s_uncertainty``."""

    s: float
    stack: Stack
    theta: np.ndarray
    s_uncertainty: float
    rho_uncertainty: tuple


@dataclass(frozen=True)
class StackTrack:
    """Result of :func:`track_stack` (see :class:`~.module.tracking.ModuleTrack`); ``passages``
    lists the branch points passed continuously (:class:`StackPassage`), ``undecided``
    those whose side doubles cannot decide (:class:`StackUndecided`)."""

    final: StackEquilibrium
    end: Stack
    jumps: tuple
    status: str = 'ok'
    message: str = ''
    steps: int = 0
    passages: tuple = ()
    undecided: tuple = ()


def _one_step_track(final, end):
    """``StackTrack(final=final, end=end, jumps=(), steps=1)``, made as :func:`_end_record`
    makes its record (filling the instance dict: 0.3 us against 1.0 through the frozen
    dataclass's __init__; StackTrack has no __post_init__, and a field added to it must be
    added here too)."""
    track = object.__new__(StackTrack)
    track.__dict__.update(final=final, end=end, jumps=(), status='ok', message='', steps=1,
                          passages=(), undecided=())
    return track


def _checked_angles(theta, n):
    theta = np.asarray(theta, dtype=float)
    if theta.shape not in ((n, 2), (2 * n,)):
        raise ValueError(f'theta must have shape ({n}, 2), got {theta.shape}')
    if not np.all(np.isfinite(theta)):
        raise ValueError('theta must be finite')
    return theta.reshape(n, 2)


def _path(start, end, settings):
    """The :class:`StackPath` from start to end, its flows compiled where ``settings`` asks."""
    path = StackPath(start, end)
    if settings.compiled_flows:
        path.compile_flows()
    return path


def settle_stack(stack: Stack, theta_guess, settings: TrackerSettings = TrackerSettings()):
    """The stable equilibrium whose basin holds the configuration ``theta_guess`` (N x 2)."""
    path = _path(stack, stack, settings)
    y0 = path.state_from_angles(_checked_angles(theta_guess, len(stack)), 0.0)
    return _record(path, _continuation.settle(path, y0, 0.0, settings), 0.0)


def track_stack(start: Stack, end: Stack, state_or_theta,
                settings: TrackerSettings = TrackerSettings()) -> StackTrack:
    """Follow the stable equilibrium of the stack from ``start`` to ``end``.

    ``state_or_theta`` is a :class:`StackEquilibrium`, a tracker state, or local
    angles (N x 2) to settle from.
    """
    path = _path(start, end, settings)
    if isinstance(state_or_theta, StackEquilibrium):
        y0 = state_or_theta.state
    else:
        arr = np.asarray(state_or_theta, dtype=float)
        y0 = path.whole_turns_removed(arr) if arr.shape == (path.size,) else \
            path.state_from_angles(_checked_angles(arr, len(start)), 0.0)
    known = (state_or_theta if isinstance(state_or_theta, StackEquilibrium)
             and state_or_theta.parameters == start._bytes else None)
    quick = whole_command_step(path, y0, settings, known)
    if quick is not None:
        y1, eigenvalues, energy, residual, point, factors = quick
        final = _end_record(path, y1, eigenvalues, energy, residual, point)
        keep_final_point(final, path, point, factors)
        return _one_step_track(final, end)
    result = _continuation.track_settled(path, y0, settings,
                                         known.certificate if known else '')
    jumps = tuple(StackJump(kind=e.kind, s=e.s, stack=path.params(e.s),
                            from_theta=path.angles(e.state, e.s),
                            to_theta=path.angles(e.landing, e.landing_s), ambiguous=e.ambiguous,
                            landing_stack=path.params(e.landing_s))
                  for e in result.events)
    passages = tuple(StackPassage(s=s, stack=path.params(s), theta=path.angles(y, s))
                     for s, y in result.passages)
    reached = end if result.s == 1.0 else path.params(result.s)
    final = _record(path, result.state, result.s, certificate=result.certificate)
    return StackTrack(final=final, end=reached, jumps=jumps, status=result.status,
                      message=result.message, steps=result.steps, passages=passages,
                      undecided=tuple(_undecided(path, u, start, end) for u in result.undecided))


def _undecided(path, undecided, start, end):
    """The :class:`StackUndecided` of a tracker's :class:`.continuation.Undecided`."""
    span = tuple(undecided.s_uncertainty * abs(b.rho - a.rho)
                 for a, b in zip(start.modules, end.modules))
    return StackUndecided(undecided.s, path.params(undecided.s),
                          path.angles(undecided.state, undecided.s), undecided.s_uncertainty, span)


def _angle_distance(path, a, b):
    """Largest difference of the rod angles of two states, modulo 2 pi."""
    n = path.topology.n_rods
    d = (np.asarray(a[:n]) - np.asarray(b[:n]) + math.pi) % (2.0 * math.pi) - math.pi
    return float(np.max(np.abs(d)))


def stack_equilibria(stack: Stack, starts=64, seed=0):
    """Equilibria of a stack by multi-start search (for tests and the CLI), sorted by energy.

    Newton on the KKT system from ``starts`` random configurations finds
    equilibria of every type; overdamped settles from ``starts // 4`` more
    sample the basins of the minima, so stable equilibria are not left to the
    luck of Newton.  Not guaranteed complete (there is no polynomial
    elimination for N > 1), but with enough starts it finds every equilibrium
    of a small stack.
    """
    path = StackPath(stack, stack)
    rng = np.random.default_rng(seed)
    scale = float(np.max([max(m.ka, m.kb, m.kc) for m in stack.modules]))
    found = []

    def add(y):
        if (np.all(np.isfinite(y)) and np.max(np.abs(path.residual(y, 0.0))) <= 1e-9 * scale
                and all(_angle_distance(path, y, f) >= 1e-7 for f in found)):
            found.append(y)

    for _ in range(starts):
        y0 = path.state_from_angles(rng.uniform(-math.pi, math.pi, (len(stack), 2)), 0.0)
        with np.errstate(all='ignore'):
            sol = root(lambda y: path.residual(y, 0.0), y0, jac=lambda y: path.jacobian(y, 0.0),
                       method='hybr', options={'xtol': 1e-13})
        add(sol.x)
    for _ in range(max(4, starts // 4)):
        y0 = path.state_from_angles(rng.uniform(-math.pi, math.pi, (len(stack), 2)), 0.0)
        try:
            add(_continuation.settle(path, y0, 0.0))
        except _continuation.TrackingError:
            pass
    records = [_record(path, y, 0.0) for y in found]
    return sorted(records, key=lambda r: r.energy)
