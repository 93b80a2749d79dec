"""A neck as a mechanism of nodes and springs only: an independent landing reference.

Written for the tests; shares no code with ``tensegrity_ros.core`` nor with
``reference_paths.py``.  The moving nodes A3(i), A4(i) of an N-module neck are free
points in the plane (4N coordinates; A1(0), A2(0) are fixed).  Every rigid length
(both rods of every module, every chord |A3(i) - A4(i)| = rho(i + 1)) is a stiff
linear spring of stiffness ``stiffness`` and rest length the rigid length; the
module springs a, b, c have zero free length (docs/model.md section 1); the loads are
constant node forces in the base frame.  Two overdamped motions, integrated with
scipy's LSODA: node drag (dx/dt = -grad E, the same drag on
every node coordinate) and pivot damping (the local angles' gradient flow with the
rods rigid and the chords stiff: viscous damping on every pivot, as in
core/dynamics/neck_snap.py).  There are no constraint multipliers and no projections, so
nothing degenerates where a module lies flat: the stiff springs carry the flow
through a linkage's change point as a real, slightly compliant mechanism would.

Rest points are then checked in the rigid model, in node coordinates: Newton on the
KKT system of all rigid lengths, and the reduced Hessian of the Lagrangian on the
tangent space of the rigid lengths (N/m, orthonormal node displacements) must be
positive definite.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.integrate import LSODA
from scipy.linalg import null_space

#: Evaluations of the flow's velocity one flow may use before it gives up (FlowUndecided):
#: a bounded time on any machine (~4 s).  The flows of test_perfect_chord_ramp_landing.py
#: use at most 7.0e3 under the Haswell, Sandybridge, Nehalem and SkylakeX kernels.
MAX_FLOW_EVALUATIONS = 100_000


class FlowUndecided(RuntimeError):
    """The flow did not come to rest within its budget of evaluations: the case is
    undecided by this model (not a result about the mechanism)."""


class NodeSpringNeck:
    """N modules as nodes and springs.  ``modules``: sequence of objects with the
    attributes rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y (bottom to top; rod weights
    must be zero).  Node table: 0 = A1(0), 1 = A2(0) (fixed), 2 + 2i = A3(i),
    3 + 2i = A4(i)."""

    def __init__(self, modules, stiffness):
        self.n = n = len(modules)
        if any(m.m1 or m.m2 for m in modules):
            raise ValueError('rod weights are not modelled here')
        a3 = lambda i: 2 + 2 * i                       # noqa: E731
        a4 = lambda i: 3 + 2 * i                       # noqa: E731
        a1 = lambda i: 0 if i == 0 else a4(i - 1)      # noqa: E731
        a2 = lambda i: 1 if i == 0 else a3(i - 1)      # noqa: E731
        self.fixed = np.array([[0.0, 0.0], [modules[0].rho, 0.0]])
        self.springs = []                  # (node, node, k): zero free length
        self.rigid = []                    # (node, node, length)
        self.loads = np.zeros((2 + 2 * n, 2))
        for i, m in enumerate(modules):
            self.springs += [(a2(i), a3(i), m.ka), (a1(i), a4(i), m.kb), (a3(i), a4(i), m.kc)]
            self.rigid += [(a1(i), a3(i), m.L1), (a2(i), a4(i), m.L2)]
            if i + 1 < n:
                self.rigid.append((a3(i), a4(i), modules[i + 1].rho))
            self.loads[a3(i)] += (m.f3x, m.f3y)
            self.loads[a4(i)] += (m.f4x, m.f4y)
        self.stiffness = float(stiffness)
        self.spring_incidence = _incidence([(a, b) for a, b, _ in self.springs], 2 + 2 * n)
        self.spring_k = np.array([k for _, _, k in self.springs])
        self.rigid_incidence = _incidence([(a, b) for a, b, _ in self.rigid], 2 + 2 * n)
        self.rigid_length = np.array([length for _, _, length in self.rigid])

    # -- node tables ---------------------------------------------------------------
    def all_nodes(self, x):
        return np.vstack([self.fixed, np.asarray(x, dtype=float).reshape(-1, 2)])

    def nodes_from_angles(self, theta):
        """Moving node coordinates (..., 4N) from local angles (..., N, 2) or (..., 2N),
        docs/model.md sections 1 and 4: module i's frame has its origin at A1(i) and its x axis
        along A1 -> A2.  Complex angles are fine (complex steps)."""
        theta = np.asarray(theta)
        if theta.shape[-2:] != (self.n, 2):               # flat states (..., 2N)
            theta = theta.reshape(theta.shape[:-1] + (self.n, 2))
        a1, a2 = self.fixed[0] + 0 * theta[..., 0, :1], self.fixed[1] + 0 * theta[..., 0, :1]
        out = []
        for i in range(self.n):
            t1, t2 = theta[..., i, 0:1], theta[..., i, 1:2]
            length1, length2 = self.rigid_length[3 * i], self.rigid_length[3 * i + 1]
            d = a2 - a1
            ex = d / np.sqrt(np.sum(d * d, axis=-1, keepdims=True))
            ey = np.concatenate([-ex[..., 1:], ex[..., :1]], axis=-1)
            a3 = a1 + length1 * (np.cos(t1) * ex + np.sin(t1) * ey)
            a4 = a2 + length2 * (-np.cos(t2) * ex + np.sin(t2) * ey)
            out += [a3, a4]
            a1, a2 = a4, a3
        return np.concatenate(out, axis=-1)

    def angles(self, x):
        """Local angles (N x 2) of a node configuration (inverse of nodes_from_angles)."""
        nodes = self.all_nodes(x)
        out = np.empty((self.n, 2))
        a1, a2 = nodes[0], nodes[1]
        for i in range(self.n):
            a3, a4 = nodes[2 + 2 * i], nodes[3 + 2 * i]
            ex = (a2 - a1) / np.linalg.norm(a2 - a1)
            ey = np.array([-ex[1], ex[0]])
            r1, r2 = a3 - a1, a4 - a2
            out[i] = math.atan2(r1 @ ey, r1 @ ex), math.atan2(r2 @ ey, -(r2 @ ex))
            a1, a2 = a4, a3
        return out

    # -- energy of the compliant mechanism -----------------------------------------
    def _elements(self, x):
        """(spring vectors, rigid-length vectors, their lengths) of configuration x."""
        p = self.all_nodes(x)
        rigid = self.rigid_incidence.T @ p
        return self.spring_incidence.T @ p, rigid, np.sqrt(np.sum(rigid * rigid, axis=1))

    def energy(self, x, stiff=True):
        """Springs minus load work; with ``stiff``, plus the stiff springs of the rigid
        lengths (zero on the rigid configurations)."""
        springs, _, lengths = self._elements(x)
        e = 0.5 * float(self.spring_k @ np.sum(springs * springs, axis=1))
        e -= float(np.sum(self.loads * self.all_nodes(x)))
        if stiff:
            e += 0.5 * self.stiffness * float(np.sum((lengths - self.rigid_length) ** 2))
        return e

    def gradient(self, x, stiff=True):
        """dE/dx (4N,); without ``stiff``, of the springs and loads alone."""
        springs, rigid, lengths = self._elements(x)
        forces = self.spring_k[:, None] * springs
        g = self.spring_incidence @ forces - self.loads
        if stiff:
            tension = self.stiffness * (lengths - self.rigid_length) / lengths
            g += self.rigid_incidence @ (tension[:, None] * rigid)
        return g[2:].ravel()

    def hessian(self, x, stiff=True):
        """d2E/dx2 (4N x 4N), exact; without ``stiff``, of the springs alone."""
        p = self.all_nodes(x)
        m = len(p)
        h = np.zeros((m, 2, m, 2))

        def add(a, b, block):
            h[a, :, a, :] += block
            h[b, :, b, :] += block
            h[a, :, b, :] -= block
            h[b, :, a, :] -= block

        for a, b, k in self.springs:
            add(a, b, k * np.eye(2))
        for a, b, length in (self.rigid if stiff else ()):
            d = p[a] - p[b]
            r = np.linalg.norm(d)
            u = d / r
            add(a, b, self.stiffness * ((1.0 - length / r) * np.eye(2)
                                        + length / r * np.outer(u, u)))
        return h.reshape(2 * m, 2 * m)[4:, 4:]

    # -- the overdamped flow: node drag or pivot damping ----------------------------------
    # 'node': dx/dt = -dE/dx, the same drag on every node coordinate (the metric of the
    # tracker's landing flow).  'pivot': d theta/dt = -dE/d theta in the local angles,
    # rods rigid and chords stiff springs: the overdamped limit of viscous damping on
    # every pivot's local angle rate (docs/model.md section 5, core/dynamics/neck_snap.py).
    def coordinates(self, theta, damping):
        """The flow's state for local angles theta: node coordinates or the angles."""
        return (self.nodes_from_angles(theta) if damping == 'node'
                else np.ravel(theta).astype(float))

    def to_nodes(self, y, damping):
        return y if damping == 'node' else self.nodes_from_angles(y)

    def flow_gradient(self, y, damping):
        return self.gradient(y) if damping == 'node' else self.angle_gradient(y)

    def flow_hessian(self, y, damping):
        """dE/dy's Jacobian: exact for nodes, central differences of the complex-step
        angle gradient for the pivots."""
        if damping == 'node':
            return self.hessian(y)
        h = 1e-6
        w = np.column_stack([(self.angle_gradient(y + h * e) - self.angle_gradient(y - h * e))
                             / (2.0 * h) for e in np.eye(y.size)])
        return 0.5 * (w + w.T)

    def equilibrium(self, y, damping, iterations=50):
        """Newton on dE/dy = 0 from y: (y*, Hessian eigenvalues, modes), in the flow's
        coordinates (whose metric is the identity: the modes are the flow's)."""
        scale = float(np.max(np.abs(self.loads))) + float(np.max(self.spring_k))
        for _ in range(iterations):
            g = self.flow_gradient(y, damping)
            if np.max(np.abs(g)) < 1e-12 * scale:
                break
            y = y - np.linalg.solve(self.flow_hessian(y, damping), g)
        values, modes = np.linalg.eigh(self.flow_hessian(y, damping))
        return y, values, modes

    def angle_gradient(self, theta):
        """dE/d(local angles) with the rods rigid and the chords stiff springs: the
        complex-step Jacobian of the forward kinematics times the node gradient."""
        theta = np.asarray(theta, dtype=float).ravel()
        h = 1e-30
        probes = self.nodes_from_angles(theta + 1j * h * np.eye(theta.size))
        return (probes.imag / h) @ self.gradient(probes[0].real)

    def flow(self, y0, damping, t_end=1e5, rest_speed=1e-9, budget=MAX_FLOW_EVALUATIONS):
        """Where dy/dt = -dE/dy from y0 comes to rest: (y, t), y the first state the
        integrator (LSODA) steps on whose speed is below ``rest_speed``, else the state at
        t_end.  Checked after each step on the state itself, not by solve_ivp's terminal
        event: the event's root is solved on the step's interpolant, whose speed near
        1e-9 N is rounding (stiff springs of 1e6 N/m times ~1e-16 m), so brentq found no
        sign change on some BLAS kernels ('f(a) and f(b) must have different signs').
        (Nor in legs of solve_ivp calls: each restarts LSODA in its non-stiff mode, which
        on one kernel did not leave it in 2e5 evaluations.)  More than ``budget``
        evaluations of the flow: :class:`FlowUndecided`, in bounded time."""
        jac = (lambda _, y: -self.hessian(y)) if damping == 'node' else None
        solver = LSODA(lambda _, y: -self.flow_gradient(y, damping), 0.0,
                       np.asarray(y0, dtype=float), t_end, rtol=1e-9, atol=1e-11, jac=jac)
        while solver.status == 'running':
            solver.step()
            if np.linalg.norm(self.flow_gradient(solver.y, damping)) < rest_speed:
                break
            if solver.nfev > budget:
                raise FlowUndecided(f'the {damping} flow did not come to rest within {budget} '
                                    f'evaluations (t = {solver.t:g} of {t_end:g})')
        if solver.status == 'failed':
            raise RuntimeError(solver.message)
        return solver.y, solver.t

    # -- the rigid model ------------------------------------------------------------
    def rigid_jacobian(self, x):
        """Gradients of the rigid lengths |Xa - Xb| (rows) in the moving coordinates."""
        p = self.all_nodes(x)
        jac = np.zeros((len(self.rigid), len(p), 2))
        for row, (a, b, _) in enumerate(self.rigid):
            u = (p[a] - p[b]) / np.linalg.norm(p[a] - p[b])
            jac[row, a] += u
            jac[row, b] -= u
        return jac.reshape(len(self.rigid), -1)[:, 4:]

    def rigid_residuals(self, x):
        p = self.all_nodes(x)
        return np.array([np.linalg.norm(p[a] - p[b]) - length for a, b, length in self.rigid])

    def rigid_forces(self, x):
        """Least-squares multipliers of the rigid lengths (their tensions, N)."""
        g = self.gradient(x, stiff=False)
        return -np.linalg.lstsq(self.rigid_jacobian(x).T, g, rcond=None)[0]

    def lagrangian_hessian(self, x, mu):
        """Hessian of springs - loads + sum mu_e |Xa - Xb|."""
        p = self.all_nodes(x)
        m = len(p)
        h = np.zeros((m, 2, m, 2))
        for (a, b, _), force in zip(self.rigid, mu):
            d = p[a] - p[b]
            r = np.linalg.norm(d)
            u = d / r
            block = force / r * (np.eye(2) - np.outer(u, u))
            h[a, :, a, :] += block
            h[b, :, b, :] += block
            h[a, :, b, :] -= block
            h[b, :, a, :] -= block
        return self.hessian(x, stiff=False) + h.reshape(2 * m, 2 * m)[4:, 4:]

    def rigid_polish(self, x, iterations=50, tol=1e-12):
        """Newton on the KKT system of the rigid model from x: (x*, mu*, largest
        residual), mu the tensions of the rigid lengths (N)."""
        x = np.asarray(x, dtype=float).copy()
        mu = self.rigid_forces(x)
        r = len(self.rigid)
        for _ in range(iterations):
            jac = self.rigid_jacobian(x)
            residual = np.concatenate([self.gradient(x, stiff=False) + jac.T @ mu,
                                       self.rigid_residuals(x)])
            if np.max(np.abs(residual)) < tol:
                break
            kkt = np.block([[self.lagrangian_hessian(x, mu), jac.T], [jac, np.zeros((r, r))]])
            step = np.linalg.solve(kkt, -residual)
            x += step[:x.size]
            mu += step[x.size:]
        return x, mu, float(np.max(np.abs(residual)))

    def reduced_eigen(self, x, mu):
        """Eigenvalues and node-space modes of the Lagrangian's Hessian on the tangent
        space of the rigid lengths (orthonormal node displacements: N/m)."""
        z = null_space(self.rigid_jacobian(x))
        values, vectors = np.linalg.eigh(z.T @ self.lagrangian_hessian(x, mu) @ z)
        return values, z @ vectors

    def rigid_energy(self, x):
        return self.energy(x, stiff=False)


@dataclass(frozen=True)
class Landing:
    """A rest point checked in the rigid model: local angles (N x 2), energy (J),
    reduced-Hessian eigenvalues (N/m) and KKT residual."""

    theta: np.ndarray
    energy: float
    eigenvalues: np.ndarray
    residual: float


def rest_point(past, at, y0, damping):
    """Where the mechanism ``past`` (a :class:`NodeSpringNeck`, the load frozen) released
    at y0 (its flow coordinates) comes to rest under ``damping`` ('node' or 'pivot'),
    polished and checked in the rigid model ``at``."""
    rest, _ = past.flow(y0, damping)
    x, mu, residual = at.rigid_polish(past.to_nodes(rest, damping))
    eigenvalues, _ = at.reduced_eigen(x, mu)
    return Landing(at.angles(x), at.rigid_energy(x), eigenvalues, residual)


def released_past_a_branch_point(past, theta_star, damping, push, sign):
    """(start, softest eigenvalue): ``past``'s equilibrium next to the critical state
    theta_star pushed off by sign * push along its softest mode (a branch point's
    branch goes on past it, as a saddle once past: the eigenvalue is then negative)."""
    y, values, modes = past.equilibrium(past.coordinates(theta_star, damping), damping)
    return y + sign * push * modes[:, 0], float(values[0])


def _incidence(ends, nodes):
    """Node-by-element matrix: +1 at an element's first end, -1 at its second."""
    matrix = np.zeros((nodes, len(ends)))
    for column, (a, b) in enumerate(ends):
        matrix[a, column] += 1.0
        matrix[b, column] -= 1.0
    return matrix
