"""The neck stack: N modules with coupled statics (DESIGN.md section 4).

Module i+1 sits on module i's top chord: A1(i+1) = A4(i), A2(i+1) = A3(i), and
module i+1's telescopic rod is that chord, |A3(i) - A4(i)| = rho(i+1).  Module
i+1's base frame has its origin at A4(i) and its x axis along A4(i) -> A3(i).

Coordinates.  The unknowns are the positions of every moving node (A3, A4 of
each module, in the stack's base frame) and one Lagrange multiplier per rigid
length: both rods of every module and every chord.  In these coordinates the
energy (zero-free-length springs, constant loads) and the length constraints
are quadratic, so all derivatives are exact and cheap.  Equilibria are KKT
points; stability is the reduced Hessian (the Hessian of the Lagrangian on
the tangent space of the constraints) being positive definite.  Its
eigenvalues are stiffnesses in N/m along orthonormal node displacements (for
one module the module solver reports J/rad^2 along the angles instead: same
signs, same critical points, different units).

Every module keeps its A3A4 spring.  In a lower module it is in parallel with
the chord (a rigid length), so it has no effect on equilibria or stability;
it only loads the actuator of the module above, as a real stack of identical
modules would.  Loads are given in the base frame; a uniform rod's weight is
split exactly into half its weight at each end (a lower end resting on a
lower module loads that module).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from . import continuation as _continuation
from .continuation import TrackerSettings
from .module import ModuleParams, PARAMETER_NAMES, InvalidParameterError

_P = {name: i for i, name in enumerate(PARAMETER_NAMES)}
_FIXED = 2          # A1(0) and A2(0) are the first two entries of the node table
# Landing flow near kinematic singularities: the constraint Gram matrix (entries ~1)
# is damped by up to _DAMPING once its smallest eigenvalue falls below _DAMPING_ONSET.
_DAMPING = 1e-3
_DAMPING_ONSET = 1e-2


def _solve_gram(jc, rhs):
    """(J J^T)^-1 rhs, or the least-squares answer where the constraints are dependent
    (a kinematically singular stack: rods folded flat onto a chord, or degenerate sizes)."""
    try:
        return np.linalg.solve(jc @ jc.T, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(jc @ jc.T, rhs, rcond=None)[0]


@dataclass(frozen=True)
class Stack:
    """Modules bottom to top.  ``modules[i].rho`` is module i's actuator length
    (for i >= 1: the length of module i-1's top chord)."""

    modules: tuple

    def __post_init__(self):
        modules = tuple(self.modules)
        if not modules:
            raise InvalidParameterError('a stack needs at least one module')
        for i, m in enumerate(modules):
            if not isinstance(m, ModuleParams):
                raise InvalidParameterError(
                    f'module {i} must be ModuleParams, got {type(m).__name__}')
        if len({m.g for m in modules}) != 1:
            raise InvalidParameterError('all modules must use the same gravity')
        object.__setattr__(self, 'modules', modules)

    def __len__(self):
        return len(self.modules)

    def vector(self):
        return np.concatenate([m.vector() for m in self.modules])

    def from_vector(self, values):
        values = np.asarray(values, dtype=float).reshape(len(self), len(PARAMETER_NAMES))
        return Stack(tuple(ModuleParams.from_vector(v, g=self.modules[0].g) for v in values))

    def with_module(self, index, **changes):
        modules = list(self.modules)
        modules[index] = modules[index].with_(**changes)
        return Stack(tuple(modules))


class _Topology:
    """Index tables of the node graph of an N-module stack.

    Node table: 0 = A1(0), 1 = A2(0) (fixed), 2 + 2i = A3(i), 3 + 2i = A4(i).
    """

    def __init__(self, n):
        self.n = n
        a3 = lambda i: 2 + 2 * i
        a4 = lambda i: 3 + 2 * i
        a1 = lambda i: 0 if i == 0 else a4(i - 1)
        a2 = lambda i: 1 if i == 0 else a3(i - 1)
        self.a1, self.a2, self.a3, self.a4 = a1, a2, a3, a4
        self.nodes = 2 + 2 * n
        # springs: (a, b, module, parameter) for ka: A2A3, kb: A1A4, kc: A3A4
        springs = []
        for i in range(n):
            springs += [(a2(i), a3(i), i, 'ka'), (a1(i), a4(i), i, 'kb'), (a3(i), a4(i), i, 'kc')]
        # rigid lengths: (a, b, module, parameter): rods L1, L2, chords rho of the module above
        rigid = []
        for i in range(n):
            rigid += [(a1(i), a3(i), i, 'L1'), (a2(i), a4(i), i, 'L2')]
            if i + 1 < n:
                rigid.append((a3(i), a4(i), i + 1, 'rho'))
        self.spring_ends = np.array([(a, b) for a, b, _, _ in springs])
        self.spring_params = [(i, _P[name]) for _, _, i, name in springs]
        self.rigid_ends = np.array([(a, b) for a, b, _, _ in rigid])
        self.rigid_params = [(i, _P[name]) for _, _, i, name in rigid]
        self.springs_incidence = _incidence(self.spring_ends, self.nodes)
        self.rigid_incidence = _incidence(self.rigid_ends, self.nodes)
        self.n_var = 4 * n
        self.n_rigid = len(rigid)


def _expand(node_matrix):
    """kron(node_matrix[moving, moving], I2): node couplings to coordinate couplings."""
    m = node_matrix[_FIXED:, _FIXED:]
    out = np.zeros((2 * m.shape[0], 2 * m.shape[1]))
    out[0::2, 0::2] = m
    out[1::2, 1::2] = m
    return out


@functools.lru_cache(maxsize=32)
def _topology(n):
    return _Topology(n)


def _incidence(ends, nodes):
    """Node-by-element matrix with +1 at the first end and -1 at the second."""
    matrix = np.zeros((nodes, len(ends)))
    matrix[ends[:, 0], np.arange(len(ends))] = 1.0
    matrix[ends[:, 1], np.arange(len(ends))] -= 1.0
    return matrix


class _Loads:
    """Per-node external force (base frame) from the module parameters (nodes x 2)."""

    @staticmethod
    def build(topology, values, g):
        loads = np.zeros((topology.nodes, 2))
        for i, v in enumerate(values):
            loads[topology.a3(i)] += (v[_P['f3x']], v[_P['f3y']])
            loads[topology.a4(i)] += (v[_P['f4x']], v[_P['f4y']])
            half1, half2 = 0.5 * v[_P['m1']] * g, 0.5 * v[_P['m2']] * g
            loads[topology.a1(i), 1] -= half1
            loads[topology.a3(i), 1] -= half1
            loads[topology.a2(i), 1] -= half2
            loads[topology.a4(i), 1] -= half2
        return loads


class StackPath:
    """A stack along p(s) = start + s (end - start), as a tracker PathProblem.

    State y = [moving node coordinates (4N), multipliers of the rigid lengths (3N - 1)].
    Constraints are scaled as (|Xa - Xb|^2 - l^2) / (2 l_ref) (metres) so that
    the multipliers are forces (N) and the KKT matrix is symmetric.
    """

    def __init__(self, start: Stack, end: Stack):
        if len(start) != len(end):
            raise InvalidParameterError('start and end stacks differ in size')
        self.start, self.end = start, end
        self.topology = _topology(len(start))
        self.n = len(start)
        self.size = self.topology.n_var + self.topology.n_rigid
        self.p0 = start.vector()
        self.dp = end.vector() - self.p0
        self.g = start.modules[0].g
        lengths = [m.L1 for m in start.modules] + [m.L2 for m in start.modules]
        self.l_ref = float(np.mean(lengths))
        self.state_weights = np.concatenate([np.full(self.topology.n_var, 1.0 / self.l_ref),
                                             np.zeros(self.topology.n_rigid)])
        self._cache_s = None
        self._precompute()

    # -- parameters at s -------------------------------------------------------
    def _precompute(self):
        """Everything the path needs at s = 0 and its rate along s (all linear in s)."""
        top = self.topology
        ends = [v.reshape(self.n, len(PARAMETER_NAMES)) for v in (self.p0, self.p0 + self.dp)]
        k = [np.array([v[i, j] for i, j in top.spring_params]) for v in ends]
        lengths = [np.array([v[i, j] for i, j in top.rigid_params]) for v in ends]
        loads = [_Loads.build(top, v, self.g) for v in ends]
        stiffness = [_expand(top.springs_incidence @ np.diag(kk) @ top.springs_incidence.T)
                     for kk in k]
        pairs = {'k': k, 'len': lengths, 'loads': loads, 'stiffness': stiffness,
                 'rho0': [v[0, _P['rho']] for v in ends]}
        self._base = {name: a for name, (a, b) in pairs.items()}
        self._rate = {name: b - a for name, (a, b) in pairs.items()}

    def _at(self, s):
        if s != self._cache_s:
            base, rate = self._base, self._rate
            self._k = base['k'] + s * rate['k']
            self._len = base['len'] + s * rate['len']
            self._loads = base['loads'] + s * rate['loads']
            self._stiffness = base['stiffness'] + s * rate['stiffness']
            self._rho0 = base['rho0'] + s * rate['rho0']
            self._cache_s = s
        return self

    def params(self, s):
        return self.start.from_vector(self.p0 + s * self.dp)

    def admissible(self, s):
        try:
            self.params(s)
        except ValueError:
            return False
        return True

    def nodes(self, y, s):
        """All node positions (nodes x 2) including the fixed A1(0), A2(0)."""
        self._at(s)
        table = np.empty((self.topology.nodes, 2))
        table[0] = 0.0
        table[1] = (self._rho0, 0.0)
        table[_FIXED:] = np.asarray(y[:self.topology.n_var]).reshape(-1, 2)
        return table

    # -- pieces ------------------------------------------------------------------
    def _parts(self, y, s):
        top = self.topology
        x = self.nodes(y, s)
        mu = np.asarray(y[top.n_var:])
        d_spring = top.springs_incidence.T @ x                  # (springs, 2) Xa - Xb
        d_rigid = top.rigid_incidence.T @ x                     # (rigid, 2)
        return x, mu, d_spring, d_rigid

    def _constraints(self, d_rigid):
        return (np.einsum('ij,ij->i', d_rigid, d_rigid) - self._len ** 2) / (2.0 * self.l_ref)

    def _constraint_jacobian(self, d_rigid):
        """d c / d(moving coordinates), (rigid, 4N)."""
        top = self.topology
        full = top.rigid_incidence.T[:, :, None] * d_rigid[:, None, :] / self.l_ref
        return full[:, _FIXED:, :].reshape(top.n_rigid, top.n_var)

    def _internal_forces(self, d_spring, d_rigid, mu):
        """dL_internal/dX for every node (nodes x 2): springs plus rigid-length forces."""
        top = self.topology
        return (top.springs_incidence @ (self._k[:, None] * d_spring)
                + top.rigid_incidence @ ((mu / self.l_ref)[:, None] * d_rigid))

    # -- PathProblem ---------------------------------------------------------------
    def residual(self, y, s):
        x, mu, d_spring, d_rigid = self._parts(y, s)
        grad = self._internal_forces(d_spring, d_rigid, mu) - self._loads
        return np.concatenate([grad[_FIXED:].ravel(), self._constraints(d_rigid)])

    def _lagrangian_hessian(self, mu):
        top = self.topology
        nodes_mu = (top.rigid_incidence * (mu / self.l_ref)) @ top.rigid_incidence.T
        return self._stiffness + _expand(nodes_mu)

    def jacobian(self, y, s):
        x, mu, d_spring, d_rigid = self._parts(y, s)
        jc = self._constraint_jacobian(d_rigid)
        m = self.topology.n_rigid
        return np.block([[self._lagrangian_hessian(mu), jc.T], [jc, np.zeros((m, m))]])

    def residual_s(self, y, s):
        # The residual is at most quadratic in s along a straight path, so the central
        # difference is exact up to rounding.
        h = 1e-3
        return (self.residual(y, s + h) - self.residual(y, s - h)) / (2.0 * h)

    def energy(self, y, s):
        """The Lagrangian U + mu . c (equal to U on the constraint manifold)."""
        x, mu, d_spring, d_rigid = self._parts(y, s)
        springs = 0.5 * float(self._k @ np.einsum('ij,ij->i', d_spring, d_spring))
        return springs - float(np.sum(self._loads * x)) + float(mu @ self._constraints(d_rigid))

    def energy_s(self, y, s):
        h = 1e-3
        return (self.energy(y, s + h) - self.energy(y, s - h)) / (2.0 * h)

    def _reduced(self, y, s):
        x, mu, d_spring, d_rigid = self._parts(y, s)
        jc = self._constraint_jacobian(d_rigid)
        w = self._lagrangian_hessian(mu)
        q, _ = np.linalg.qr(jc.T, mode='complete')       # jc has full row rank
        z = q[:, jc.shape[0]:]
        return jc, w, z

    def eigenvalues(self, y, s):
        jc, w, z = self._reduced(y, s)
        return np.linalg.eigvalsh(z.T @ w @ z)

    def stability(self, y, s):
        """Reduced-Hessian eigenvalues and the matching KKT-space modes (Z v, d mu)."""
        jc, w, z = self._reduced(y, s)
        values, vectors = np.linalg.eigh(z.T @ w @ z)
        dx = z @ vectors
        dmu = -_solve_gram(jc, jc @ w @ dx)
        return values, np.vstack([dx, dmu])

    def descent(self, y, s):
        """Overdamped velocity: the projected force plus a pull back onto the constraints."""
        x, mu, d_spring, d_rigid = self._parts(y, s)
        grad = (self._internal_forces(d_spring, d_rigid, np.zeros_like(mu)) - self._loads)[_FIXED:].ravel()
        jc = self._constraint_jacobian(d_rigid)
        # Damped (Levenberg) projection: smooth through kinematic singularities of the
        # stack, where rods fold flat onto a chord and the constraint rows degenerate.
        gram = jc @ jc.T
        smallest = np.linalg.eigvalsh(gram)[0]
        if smallest < _DAMPING_ONSET:
            gram = gram + _DAMPING * (1.0 - smallest / _DAMPING_ONSET) ** 2 * np.eye(len(mu))
        tangential = grad - jc.T @ np.linalg.solve(gram, jc @ grad)
        restoring = jc.T @ np.linalg.solve(gram, self._constraints(d_rigid))
        rate = float(np.max(self._k)) * 2.0
        return np.concatenate([-tangential - rate * restoring, np.zeros_like(mu)])

    def project(self, y, s):
        """Nearest admissible positions (Gauss-Newton) and least-squares multipliers."""
        top = self.topology
        y = np.array(y, dtype=float)
        for _ in range(50):
            x, mu, d_spring, d_rigid = self._parts(y, s)
            c = self._constraints(d_rigid)
            if np.max(np.abs(c)) < 1e-15 * self.l_ref:
                break
            jc = self._constraint_jacobian(d_rigid)
            y[:top.n_var] -= jc.T @ _solve_gram(jc, c)
        x, mu, d_spring, d_rigid = self._parts(y, s)
        jc = self._constraint_jacobian(d_rigid)
        grad = (self._internal_forces(d_spring, d_rigid, np.zeros_like(mu)) - self._loads)[_FIXED:].ravel()
        y[top.n_var:] = -_solve_gram(jc, jc @ grad)
        return y

    # -- reporting ---------------------------------------------------------------
    def angles(self, y, s):
        """Local angles (N x 2): t1 of A1A3 from the module's x axis, t2 of A2A4 from -x."""
        x = self.nodes(y, s)
        top = self.topology
        out = np.empty((self.n, 2))
        for i in range(self.n):
            o, a2, a3, a4 = x[top.a1(i)], x[top.a2(i)], x[top.a3(i)], x[top.a4(i)]
            e = (a2 - o) / np.hypot(*(a2 - o))
            v3, v4 = a3 - o, a4 - a2
            out[i, 0] = math.atan2(e[0] * v3[1] - e[1] * v3[0], e @ v3)
            out[i, 1] = math.atan2(e[0] * v4[1] - e[1] * v4[0], -(e @ v4))
        return out

    def state_from_angles(self, theta, s):
        """Forward kinematics from local angles (N x 2), projected onto the constraints."""
        theta = np.asarray(theta, dtype=float).reshape(self.n, 2)
        self._at(s)
        values = (self.p0 + s * self.dp).reshape(self.n, len(PARAMETER_NAMES))
        top = self.topology
        x = np.zeros((top.nodes, 2))
        x[1] = (self._rho0, 0.0)
        for i in range(self.n):
            o, a2 = x[top.a1(i)], x[top.a2(i)]
            e = (a2 - o) / np.hypot(*(a2 - o))
            n = np.array([-e[1], e[0]])
            v = values[i]
            t1, t2 = theta[i]
            x[top.a3(i)] = o + v[_P['L1']] * (math.cos(t1) * e + math.sin(t1) * n)
            x[top.a4(i)] = a2 + v[_P['L2']] * (-math.cos(t2) * e + math.sin(t2) * n)
        y = np.concatenate([x[_FIXED:].ravel(), np.zeros(top.n_rigid)])
        return self.project(y, s)

    def actuator_forces(self, y, s):
        """dU*/d rho of every module (N): the force each telescopic actuator holds."""
        x, mu, d_spring, d_rigid = self._parts(y, s)
        forces = np.empty(self.n)
        internal = self._internal_forces(d_spring, d_rigid, mu)
        forces[0] = internal[1, 0]                         # A2(0) moves along +x with rho(0)
        chord = [j for j, (i, p) in enumerate(self.topology.rigid_params) if p == _P['rho']]
        for module, j in zip(range(1, self.n), chord):
            forces[module] = -mu[j] * self._len[j] / self.l_ref
        return forces

    def base_reaction(self, y, s):
        """Force (2,) and moment about A1(0) that the ground supplies at A1(0) and A2(0)."""
        x, mu, d_spring, d_rigid = self._parts(y, s)
        support = self._internal_forces(d_spring, d_rigid, mu)[:_FIXED] - self._loads[:_FIXED]
        moment = float(np.sum(x[:_FIXED, 0] * support[:, 1] - x[:_FIXED, 1] * support[:, 0]))
        return support.sum(axis=0), moment

    def total_load(self, y, s):
        """Resultant external force (2,) and its moment about A1(0), all nodes."""
        x = self.nodes(y, s)
        loads = self._loads
        return loads.sum(axis=0), float(np.sum(x[:, 0] * loads[:, 1] - x[:, 1] * loads[:, 0]))

    def head_pose(self, y, s):
        """Midpoint (2,) and direction angle (rad) of the top chord A4 -> A3."""
        x = self.nodes(y, s)
        top = self.topology
        a3, a4 = x[top.a3(self.n - 1)], x[top.a4(self.n - 1)]
        d = a3 - a4
        return 0.5 * (a3 + a4), math.atan2(d[1], d[0])


@dataclass(frozen=True)
class StackEquilibrium:
    """A verified equilibrium of a stack.

    ``theta`` (N x 2) local angles, ``nodes`` (2 + 2N, 2) every node in the base frame
    (A1(0), A2(0), then A3(i), A4(i) for each module), ``eigenvalues`` of the reduced
    Hessian (N/m, ascending), ``actuator_forces`` (N,), ``state`` the tracker state.
    """

    theta: np.ndarray
    nodes: np.ndarray
    eigenvalues: np.ndarray
    energy: float
    actuator_forces: np.ndarray
    residual: float
    state: np.ndarray
    head_position: np.ndarray
    head_angle: float

    @property
    def stable(self):
        ev = self.eigenvalues
        return bool(ev[0] > 1e-9 * max(abs(ev[-1]), 1e-300))

    @property
    def stability_margin(self):
        return float(self.eigenvalues[0])


def _record(path, y, s):
    head_position, head_angle = path.head_pose(y, s)
    return StackEquilibrium(
        theta=path.angles(y, s), nodes=path.nodes(y, s), eigenvalues=path.eigenvalues(y, s),
        energy=path.energy(y, s), actuator_forces=path.actuator_forces(y, s),
        residual=float(np.max(np.abs(path.residual(y, s)))), state=np.array(y),
        head_position=head_position, head_angle=head_angle)


def stack_equilibrium_at(stack: Stack, state) -> StackEquilibrium:
    """The record of a tracker state of ``stack``."""
    return _record(StackPath(stack, stack), np.asarray(state, dtype=float), 0.0)


@dataclass(frozen=True)
class StackJump:
    """A jump of the stack: ``theta`` of every module before (critical) and after (landing)."""

    kind: str
    s: float
    stack: Stack
    from_theta: np.ndarray
    to_theta: np.ndarray
    ambiguous: bool = False


@dataclass(frozen=True)
class StackTrack:
    """Result of :func:`track_stack` (see :class:`~.tracking.ModuleTrack`)."""

    final: StackEquilibrium
    end: Stack
    jumps: tuple
    status: str = 'ok'
    message: str = ''
    steps: int = 0


def _checked_angles(theta, n):
    theta = np.asarray(theta, dtype=float)
    if theta.shape not in ((n, 2), (2 * n,)):
        raise ValueError(f'theta must have shape ({n}, 2), got {theta.shape}')
    if not np.all(np.isfinite(theta)):
        raise ValueError('theta must be finite')
    return theta.reshape(n, 2)


def settle_stack(stack: Stack, theta_guess, settings: TrackerSettings = TrackerSettings()):
    """The stable equilibrium whose basin holds the configuration ``theta_guess`` (N x 2)."""
    path = StackPath(stack, stack)
    y0 = path.state_from_angles(_checked_angles(theta_guess, len(stack)), 0.0)
    return _record(path, _continuation.settle(path, y0, 0.0, settings), 0.0)


def track_stack(start: Stack, end: Stack, state_or_theta,
                settings: TrackerSettings = TrackerSettings()) -> StackTrack:
    """Follow the stable equilibrium of the stack from ``start`` to ``end``.

    ``state_or_theta`` is a :class:`StackEquilibrium`, a tracker state, or local
    angles (N x 2) to settle from.
    """
    path = StackPath(start, end)
    if isinstance(state_or_theta, StackEquilibrium):
        y0 = state_or_theta.state
    else:
        arr = np.asarray(state_or_theta, dtype=float)
        y0 = arr if arr.shape == (path.size,) else path.state_from_angles(
            _checked_angles(arr, len(start)), 0.0)
    try:
        result = _continuation.track(path, y0, settings)
    except _continuation.TrackingError:
        y0 = _continuation.settle(path, path.project(y0, 0.0), 0.0, settings)
        result = _continuation.track(path, y0, settings)
    jumps = tuple(StackJump(kind=e.kind, s=e.s, stack=path.params(e.s),
                            from_theta=path.angles(e.state, e.s),
                            to_theta=path.angles(e.landing, e.landing_s), ambiguous=e.ambiguous)
                  for e in result.events)
    reached = end if result.s == 1.0 else path.params(result.s)
    final = _record(path, result.state, result.s)
    return StackTrack(final=final, end=reached, jumps=jumps, status=result.status,
                      message=result.message, steps=result.steps)


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
    n_var = path.topology.n_var
    scale = float(np.max([max(m.ka, m.kb, m.kc) for m in stack.modules]))
    found = []

    def add(y):
        if (np.all(np.isfinite(y)) and np.max(np.abs(path.residual(y, 0.0))) <= 1e-9 * scale
                and all(np.max(np.abs(y[:n_var] - f[:n_var])) >= 1e-7 for f in found)):
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
