"""The neck stack in node coordinates: the formulation the core used before its reduced
(rod-angle) form, kept as an independent reference for the tests.

State y = [moving node coordinates (4N), multipliers of every rigid length: both rods
of every module and every chord (3N - 1)].  Energy and constraints are quadratic in
the coordinates; stability is the reduced Hessian on the tangent space of all rigid
lengths, in N/m.  Same contract as :class:`tensegrity_ros.core.neck.stack.StackPath`
(a tracker PathProblem), so ``continuation.track`` runs on it unchanged.
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from tensegrity_ros.core.module.model import InvalidParameterError, PARAMETER_NAMES

if TYPE_CHECKING:       # the annotations' Stack only: the reference uses none of its code
    from tensegrity_ros.core.neck.stack import Stack

_P = {name: i for i, name in enumerate(PARAMETER_NAMES)}
_FIXED = 2
_DAMPING = 1e-3
_DAMPING_ONSET = 1e-2


def _solve_gram(jc, rhs):
    """(J J^T)^-1 rhs, or the least-squares answer where the constraints are dependent
    (a kinematically singular stack: rods folded flat onto a chord, or degenerate sizes)."""
    try:
        return np.linalg.solve(jc @ jc.T, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(jc @ jc.T, rhs, rcond=None)[0]


class _Topology:
    """Index tables of the node graph of an N-module stack.

    Node table: 0 = A1(0), 1 = A2(0) (fixed), 2 + 2i = A3(i), 3 + 2i = A4(i).
    """

    def __init__(self, n):
        self.n = n

        def a3(i):
            return 2 + 2 * i

        def a4(i):
            return 3 + 2 * i

        def a1(i):
            return 0 if i == 0 else a4(i - 1)

        def a2(i):
            return 1 if i == 0 else a3(i - 1)
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


class CartesianStackPath:
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
        grad = (self._internal_forces(d_spring, d_rigid, np.zeros_like(mu))
                - self._loads)[_FIXED:].ravel()
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
        grad = (self._internal_forces(d_spring, d_rigid, np.zeros_like(mu))
                - self._loads)[_FIXED:].ravel()
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
