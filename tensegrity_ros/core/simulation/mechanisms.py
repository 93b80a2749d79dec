"""The two solvers behind the simulator, one interface: one module, or a neck of N modules.

:class:`OneModule` runs the exact one-module tracker (``track_module``, angles as the
state) and offers what only one module has: the exact equilibrium count and the
operation range.  :class:`Neck` runs the coupled stack tracker (``track_stack``).
Both take and return tuples of :class:`ModuleParams`, bottom to top, and give every
module the same view of the verified state, so the simulator above has one code path.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .events import BranchEnd, Jump
from ..analysis.operation_range import operation_range
from ..continuation import TrackerSettings
from ..module.model import node_positions
from ..module.polynomial_solver import equilibria
from ..module.tracking import settle, track_module
from ..neck.stack import settle_stack, Stack, track_stack


@dataclass(frozen=True)
class Motion:
    """What one tracked path did: the verified ``final`` state, the module parameters
    ``end`` it holds for (the commanded end unless ``status`` is ``failed``), the jumps,
    and ``passages``: every module's parameters at each branch point passed continuously;
    ``undecided``: (every module's parameters, theta N x 2, the uncertainty in s, every
    module's rho uncertainty) of those whose side doubles cannot decide.
    ``certificate``: the tracker's (:attr:`.continuation.Track.certificate`) for ``final``."""

    final: object
    end: tuple
    jumps: tuple
    status: str
    message: str
    passages: tuple = ()
    certificate: str = ''
    undecided: tuple = ()


class ModuleView:
    """One module's view of a verified neck equilibrium, with the attributes of a
    one-module :class:`~tensegrity_ros.core.module.equilibria.Equilibrium` (theta1, theta2,
    actuator_force, stable ...).  Stability is the whole neck's: ``stability_margin`` is
    the smallest reduced-Hessian eigenvalue (N/m), ``eigenvalues`` all of them."""

    __slots__ = ('stack', 'index', 'theta', 'theta1', 'theta2', 'actuator_force', 'stable',
                 'stability_margin', 'eigenvalues', 'energy', 'residual')

    def __init__(self, stack_eq, index, thetas, forces, whole):
        """Module ``index`` of ``stack_eq``; ``thetas`` and ``forces`` are its angles and
        actuator forces as Python floats, ``whole`` the (stable, margin, energy,
        residual) of the neck: converted once for all N views (see :meth:`Neck.views`)."""
        self.stack = stack_eq
        self.index = index
        self.theta = stack_eq.theta[index]
        self.theta1, self.theta2 = thetas[index]
        self.actuator_force = forces[index]
        self.stable, self.stability_margin, self.energy, self.residual = whole
        self.eigenvalues = stack_eq.eigenvalues


def head_of(positions):
    """Midpoint (x, y) and direction angle (rad) of the top chord A4 -> A3 of one module."""
    a3, a4 = positions[2], positions[3]
    return ((float(a3[0] + a4[0]) * 0.5, float(a3[1] + a4[1]) * 0.5),
            math.atan2(float(a3[1] - a4[1]), float(a3[0] - a4[0])))


def stack_module_nodes(nodes, index):
    """A1..A4 of module ``index`` from a stack's node table (A1(0), A2(0), A3(i), A4(i))."""
    a3, a4 = 2 + 2 * index, 3 + 2 * index
    a1, a2 = (0, 1) if index == 0 else (a4 - 2, a3 - 2)
    return nodes[[a1, a2, a3, a4]]


class OneModule:
    """N = 1: the exact module tracker; margins in J/rad^2 along the angles."""

    margin_unit = 'J/rad^2'
    #: operation_range can give the live branch's stable rho interval (early warnings
    #: for every command, at the cost of a cached range)
    has_operation_range = True

    def __init__(self):
        self._count_cache = None
        self._range_cache = None

    def settle(self, modules, thetas, settings=None):
        return settle(modules[0], thetas[0])        # (a module settles without a tracker)

    def track(self, start, end, state):
        track = track_module(start[0], end[0], state.theta,
                             certificate=getattr(state, 'certificate', ''))
        jumps = [(j.kind, j.s, (j.params,), np.array([j.from_theta]), np.array([j.to_theta]),
                  j.ambiguous, (j.landing_params or j.params,)) for j in track.jumps]
        passages = tuple((params,) for params in track.passages)
        undecided = tuple(((u.params,), np.array([u.theta]), u.s_uncertainty,
                           (u.rho_uncertainty,)) for u in track.undecided)
        return Motion(track.final, (track.end,), jumps, track.status, track.message, passages,
                      track.certificate, undecided)

    def views(self, modules, state):
        return (state,)

    def normalized_margin(self, modules, state):
        """The margin over the module's stiffness scale ``min(ka, kb, kc) L1 L2``."""
        p = modules[0]
        return float(state.stability_margin) / (min(p.ka, p.kb, p.kc) * p.L1 * p.L2)

    def module_nodes(self, modules, state, index):
        return node_positions(modules[0], state.theta)

    def head(self, modules, state):
        return head_of(self.module_nodes(modules, state, 0))

    def counts(self, modules):
        """(num_equilibria, num_stable) of the module (exact, cached); a status string
        instead of the count where the equilibria are not isolated."""
        params = modules[0]
        if self._count_cache is None or self._count_cache[0] != params:
            found = equilibria(params)
            first = len(found) if found.status == 'ok' else found.status
            self._count_cache = (params, (first, found.num_stable))
        return self._count_cache[1]

    def operation_range(self, modules, state):
        """The rho interval over which the live branch stays stable (exact; cached, the
        last range as a hint so that a pure rho move costs ~20 us); None where it cannot
        be computed (a degenerate point)."""
        params = modules[0]
        key = (params, state.theta1, state.theta2)
        if self._range_cache is None or self._range_cache[0] != key:
            hint = self._range_cache[1] if self._range_cache is not None else None
            try:
                found = operation_range(params, state.theta, hint=hint)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                found = None
            self._range_cache = (key, found)
        return self._range_cache[1]


class Neck:
    """N >= 2: the coupled stack tracker; margins in N/m along node displacements."""

    margin_unit = 'N/m'
    #: no exact range for a neck: early warnings come from tracking ahead (:meth:`ahead`)
    has_operation_range = False

    def __init__(self):
        self._last = None           # (modules, Stack) of the last path's end

    def _stack(self, modules):
        """The :class:`Stack` of ``modules``: the last path's end is the next start, so
        its parameter values (kept on the Stack) are computed once, not twice."""
        if self._last is None or self._last[0] != modules:
            self._last = (modules, Stack(modules))
        return self._last[1]

    def settle(self, modules, thetas, settings=None):
        return settle_stack(Stack(modules), thetas, settings or TrackerSettings())

    def track(self, start, end, state):
        start = self._stack(start)
        self._last = (end, Stack(end))
        track = track_stack(start, self._last[1], state)
        jumps = [(j.kind, j.s, j.stack.modules, j.from_theta, j.to_theta, j.ambiguous,
                  (j.landing_stack or j.stack).modules) for j in track.jumps]
        passages = tuple(p.stack.modules for p in track.passages)
        undecided = tuple((u.stack.modules, u.theta, u.s_uncertainty, u.rho_uncertainty)
                          for u in track.undecided)
        return Motion(track.final, track.end.modules, jumps, track.status, track.message,
                      passages, track.final.certificate, undecided)

    def ahead(self, modules, state, index, rho):
        """Where the live branch ends if module ``index``'s actuator goes on to ``rho``
        with the others held (a :class:`BranchEnd`), or None: the path tracked in
        advance, a dry run that changes nothing here (the last end is not replaced).
        None too where tracking stops before a jump (the real path will say why)."""
        last = self._last
        start = last[1] if last is not None and last[0] == modules else Stack(modules)
        track = track_stack(start, start.with_module(index, rho=rho), state)
        if not track.jumps:
            return None
        first = track.jumps[0]
        return BranchEnd(rho=first.stack.modules[index].rho, kind=first.kind,
                         modules=first.stack.modules, theta=first.from_theta)

    def views(self, modules, state):
        thetas, forces = state.theta.tolist(), state.actuator_forces.tolist()
        whole = (state.stable, state.stability_margin, float(state.energy),
                 float(state.residual))
        return tuple(ModuleView(state, i, thetas, forces, whole) for i in range(len(modules)))

    def normalized_margin(self, modules, state):
        """The margin over the neck's smallest spring stiffness (N/m)."""
        return float(state.stability_margin) / min(min(m.ka, m.kb, m.kc) for m in modules)

    def module_nodes(self, modules, state, index):
        return stack_module_nodes(state.nodes, index)

    def head(self, modules, state):
        return state.head_position, state.head_angle

    def counts(self, modules):
        return None, None          # no exact enumeration for a neck

    def operation_range(self, modules, state):
        return None


def mechanism_for(count):
    """The solver for a mechanism of ``count`` modules."""
    return OneModule() if count == 1 else Neck()


def make_jump(raw, *, module, cause, count):
    """A :class:`Jump` event from a solver's raw jump tuple (kind, s, modules at the
    critical point, from_theta, to_theta, ambiguous, modules to_theta is an equilibrium of
    or ``None`` for the same)."""
    kind, s, modules, from_theta, to_theta, ambiguous, landing = raw
    return Jump(kind=kind, s=s, modules=tuple(modules), from_theta=np.asarray(from_theta),
                to_theta=np.asarray(to_theta), ambiguous=bool(ambiguous), module=module,
                cause=cause, count=count,
                landing_modules=tuple(modules if landing is None else landing))
