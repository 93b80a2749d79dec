"""Snap-through dynamics of the neck stack (docs/model.md sections 4 and 5), same contract as
:mod:`.dynamics` for one module.

Coordinates are the positions of the moving nodes (A3, A4 of every module, in the
stack's base frame).  A uniform bar between its pivot P and tip Q has kinetic
energy ``m/6 (|P'|^2 + P'.Q' + |Q'|^2)``, so the mass matrix is constant, and
its weight is exactly half at each end.  Rigid lengths (both rods of every
module; module i's top chord, whose length is module i+1's actuated rho) are
constraints ``|Xa - Xb|^2 = l(t)^2`` imposed at acceleration level with a
Baumgarte term; base node A2(0) moves along x with rho of module 0.  Each pivot
has viscous damping ``c`` on its rod's local angle rate (the dissipation
``c/2 sum theta_local'^2``).  The actuators are kinematic: every rho runs at
constant rate (the largest change sets the time) and is then held; module 0's
actuator force is the x reaction at A2(0), an upper module's is the force along
the chord that is its telescopic rod (positive pushes apart), both including the
inertia of the rods.  Local angles follow :mod:`.neck.stack` (t1 of A1A3 from the
module's x axis, t2 of A2A4 from -x), wrapped to [-pi, pi).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.integrate import OdeSolution
from scipy.linalg import eigh, null_space
from scipy.linalg.lapack import dgesv as _dgesv

from . import neck_kernel as _kernel, transient
from .transient import (imperfection_torque, NEAR, ONSET_SPEED, Rest, RhoRamp, SAME_LANDING,
                        SETTLE_TOLERANCE, SLOW, SnapHistory, SolverSettings, wrap)
from ..module.model import InvalidParameterError
from ..neck.stack import settle_stack, Stack, StackTrack, track_stack

#: Baumgarte stabilisation rate (1/s) of the length constraints.
BAUMGARTE = 20.0


@dataclass(frozen=True)
class NeckSnap:
    """Result of :func:`simulate_neck_snap`: history, summary (the keys of
    :class:`~.dynamics.Snap`; ``onset_rho`` one per module, ``final`` as
    ``{"theta": N x 2, "speed"}``) and the tracker's prediction."""

    history: SnapHistory
    summary: dict
    quasi_static: StackTrack
    solution: OdeSolution = field(repr=False)


class NeckEquations:
    """Equations of motion of an N-module neck in node coordinates along a rho ramp.

    ``damping`` is one pivot damping (N m s/rad) for every pivot, or one per module.
    ``extend_ramp``: the right-hand side continues the ramp at its rate past its end
    instead of holding (a live segment ends there; its integrator may step past the end
    only to interpolate the state at it)."""

    def __init__(self, start: Stack, ramp: RhoRamp, damping: float, extend_ramp=False):
        self.n = n = len(start)
        self.extend_ramp = extend_ramp      # the right-hand side goes on at the ramp's rate
        for i, m in enumerate(start.modules):
            if m.m1 <= 0.0 or m.m2 <= 0.0:
                raise InvalidParameterError(f'dynamics needs positive rod masses, got module '
                                            f'{i}: m1={m.m1!r}, m2={m.m2!r}')
        self.ramp = ramp
        self.imperfection = imperfection_torque(start.modules[0])    # on rod A1A3 of module 0
        self.damping = damping_vector(damping, n)
        self.pivot_damping = np.repeat(self.damping, 2)      # one per local angle
        self.modules = start.modules
        a1 = [0] + [3 + 2 * i for i in range(n - 1)]
        a2 = [1] + [2 + 2 * i for i in range(n - 1)]
        a3 = [2 + 2 * i for i in range(n)]
        a4 = [3 + 2 * i for i in range(n)]
        self.frames = list(zip(a1, a2, a3, a4))
        self.nodes = 2 + 2 * n
        mass = np.zeros((self.nodes, self.nodes))
        loads = np.zeros((self.nodes, 2))
        springs, rigid = [], []
        for i, m in enumerate(start.modules):
            for pivot, tip, rod_mass, length in ((a1[i], a3[i], m.m1, m.L1),
                                                 (a2[i], a4[i], m.m2, m.L2)):
                mass[[pivot, tip], [pivot, tip]] += rod_mass / 3.0
                mass[pivot, tip] += rod_mass / 6.0
                mass[tip, pivot] += rod_mass / 6.0
                loads[[pivot, tip], 1] -= 0.5 * rod_mass * m.g
                rigid.append((pivot, tip, length, None))
            loads[a3[i]] += (m.f3x, m.f3y)
            loads[a4[i]] += (m.f4x, m.f4y)
            springs += [(a2[i], a3[i], m.ka), (a1[i], a4[i], m.kb), (a3[i], a4[i], m.kc)]
            if i + 1 < n:
                rigid.append((a3[i], a4[i], None, i + 1))     # chord = rho of module i+1
        self.mass = np.kron(mass, np.eye(2))[4:, 4:]           # free coordinates only
        self.mass_to_free = np.kron(mass, np.eye(2))           # full (for the A2(0) reaction)
        self.loads = loads.ravel()
        self.springs, self.rigid = springs, rigid
        self.chord_rows = [j for j, r in enumerate(rigid) if r[3] is not None]
        # index arrays: the right-hand side runs on whole arrays, not per module
        self._frame_nodes = tuple(np.array(a) for a in (a1, a2, a3, a4))
        self._spring_ends = (np.array([a for a, _, _ in springs]),
                             np.array([b for _, b, _ in springs]))
        self._spring_k = np.array([k for _, _, k in springs], dtype=float)[:, None]
        self._rigid_ends = (np.array([a for a, _, _, _ in rigid]),
                            np.array([b for _, b, _, _ in rigid]))
        self._jacobian_layout()
        self._kernel_args = self._for_the_kernel(loads)
        self._base_mass_row = np.ascontiguousarray(self.mass_to_free[2, 4:])
        self._compiled = _kernel.compiled()
        self._for_numpy(loads)

    def _for_the_kernel(self, loads):
        """The arguments of :mod:`.dynamics.neck_kernel`'s evaluations after (t, y), made once."""
        contiguous = np.ascontiguousarray
        return (self.n, contiguous(self.ramp.rho0, dtype=float),
                contiguous(self.ramp.rho1, dtype=float),
                -float(self.ramp.duration) if self.extend_ramp else float(self.ramp.duration),
                contiguous(np.linalg.inv(self.mass)), contiguous(loads, dtype=float),
                contiguous([[a, b] for a, b, _ in self.springs], dtype=np.int64),
                contiguous(self._spring_k.ravel()),
                contiguous(np.array(self._frame_nodes, dtype=np.int64)),
                contiguous(self.damping, dtype=float), float(self.imperfection),
                contiguous([[a, b] for a, b, _, _ in self.rigid], dtype=np.int64),
                contiguous([0.0 if r[2] is None else r[2] for r in self.rigid], dtype=float),
                contiguous([-1 if r[3] is None else r[3] for r in self.rigid], dtype=np.int64),
                float(BAUMGARTE))

    # -- kinematics --------------------------------------------------------------------
    def full(self, t, y):
        """All node positions and velocities (nodes x 2 each) at time t."""
        x = np.empty((self.nodes, 2))
        v = np.zeros((self.nodes, 2))
        rho, rho_dot = self._ramp_now(t)
        x[0], x[1] = (0.0, 0.0), (rho[0], 0.0)
        v[1, 0] = rho_dot[0]
        k = 4 * self.n
        x[2:] = y[:k].reshape(-1, 2)
        v[2:] = y[k:].reshape(-1, 2)
        return x, v, rho, rho_dot

    def lengths(self, rho, rho_dot):
        """Target length and its rate of every rigid element."""
        length = np.array([r[2] if r[3] is None else rho[r[3]] for r in self.rigid])
        rate = np.array([0.0 if r[3] is None else rho_dot[r[3]] for r in self.rigid])
        return length, rate

    def _jacobian_layout(self):
        """Where each term of the angle Jacobian goes.  t1 of module i is
        phi(A1A3) - phi(A1A2), t2 is pi + phi(A1A2) - phi(A2A4); d phi(d) / d head =
        perp(d) / |d|^2 = -d phi / d tail.  Terms (4, N, 2): (row, sign, head, tail, d)
        = (t1, +, A3, A1, A1A3), (t1, -, A2, A1, A1A2), (t2, +, A2, A1, A1A2),
        (t2, -, A4, A2, A2A4); flat indices into the (2N, 2 nodes) matrix, heads then
        tails, so that one bincount sums every contribution."""
        a1, a2, a3, a4 = self._frame_nodes
        first = 2 * np.arange(self.n)
        rows = np.array([first, first, first + 1, first + 1])[:, :, None]
        xy = np.arange(2)
        heads = np.array([a3, a2, a2, a4])[:, :, None] * 2 + xy
        tails = np.array([a1, a1, a1, a2])[:, :, None] * 2 + xy
        width = 2 * self.nodes
        self._jac_index = np.concatenate([(rows * width + heads).ravel(),
                                          (rows * width + tails).ravel()])
        sign = np.broadcast_to(np.array([1.0, -1.0, 1.0, -1.0])[:, None, None],
                               (4, self.n, 2)).ravel()
        self._jac_sign = np.concatenate([sign, -sign])

    def angle_jacobian(self, x):
        """Local angles (2N) and d(angles)/d(all coordinates), (2N, 2 nodes)."""
        a1, a2, a3, a4 = self._frame_nodes
        d = np.stack([x[a3] - x[a1], x[a2] - x[a1], x[a4] - x[a2]])     # A1A3, A1A2, A2A4
        phi = np.arctan2(d[:, :, 1], d[:, :, 0])
        angles = np.empty(2 * self.n)
        angles[0::2] = phi[0] - phi[1]
        angles[1::2] = math.pi + phi[1] - phi[2]
        perp = np.stack([-d[:, :, 1], d[:, :, 0]], axis=-1) / np.einsum(
            'kij,kij->ki', d, d)[:, :, None]
        terms = perp[[0, 1, 1, 2]].ravel()
        values = np.concatenate([terms, terms]) * self._jac_sign
        jac = np.bincount(self._jac_index, values, minlength=4 * self.n * self.nodes)
        return wrap(angles), jac.reshape(2 * self.n, 2 * self.nodes)

    def constraint_rows(self, x, v):
        """Phi_q over all coordinates (rigid, 2 nodes), and d, d' per element."""
        a, b = self._rigid_ends
        d, dv = x[a] - x[b], v[a] - v[b]
        rows = np.zeros((len(self.rigid), 2 * self.nodes))
        element = np.arange(len(self.rigid))[:, None]
        rows[element, 2 * a[:, None] + np.arange(2)] = 2.0 * d
        rows[element, 2 * b[:, None] + np.arange(2)] = -2.0 * d
        return rows, d, dv

    def forces(self, x, v, jac):
        """Springs, loads, weights and pivot damping on all coordinates."""
        f = self.loads.copy().reshape(-1, 2)
        a, b = self._spring_ends
        pull = self._spring_k * (x[a] - x[b])
        np.add.at(f, a, -pull)
        np.add.at(f, b, pull)
        return f.ravel() - jac.T @ (self.pivot_damping * (jac @ v.ravel()))

    # -- the ODE -------------------------------------------------------------------------
    # Two evaluations of the same equations: compiled (:mod:`.dynamics.neck_kernel`, numba) where
    # it is installed, else numpy (``_solve``): the same numbers to rounding, the numpy one
    # ~10 times slower per evaluation (see neck_kernel's docstring).

    def rhs(self, t, y):
        """dy/dt: (node velocities, node accelerations)."""
        if self._compiled is not None:
            return self._compiled.state_rate(t, y, *self._kernel_args)
        return np.concatenate([y[4 * self.n:], self._solve(t, y)[0]])

    def rates(self, t, y):
        """Local angles (wrapped) and their rates."""
        if self._compiled is None:
            return self.rates_from_nodes(t, y)
        n, rho0, rho1, duration = self._kernel_args[:4]
        return self._compiled.local_angles_and_rates(
            t, np.ascontiguousarray(y, dtype=float), n, rho0, rho1, duration,
            self._kernel_args[8])

    def readings(self, t, ys):
        """(local angles, rates, actuator forces) of states ``ys`` (k, 8N) at times ``t``
        (k): every sample of a snap at once."""
        t = np.full(len(ys), float(t)) if np.ndim(t) == 0 else np.array(t, dtype=float)
        ys = np.ascontiguousarray(ys, dtype=float)
        if self._compiled is not None:
            return self._compiled.readings(t, ys, *self._kernel_args, self._base_mass_row)
        rows = [(*self.rates_from_nodes(tk, yk), self.actuator_forces(tk, yk))
                for tk, yk in zip(t, ys)]
        return tuple(np.array([row[j] for row in rows]) for j in range(3))

    def rates_from_nodes(self, t, y):
        """:meth:`rates` by the angle Jacobian (numpy)."""
        x, v, _, _ = self.full(t, y)
        angles, jac = self.angle_jacobian(x)
        return angles, jac @ v.ravel()

    def actuator_forces(self, t, y):
        """Module 0: the x force the actuator exerts on A2(0); above: 2 lambda l along the
        chord that is its telescopic rod (positive pushes apart), the rods' inertia in."""
        if self._compiled is not None:
            return self._compiled.actuator_forces(t, np.ascontiguousarray(y, dtype=float),
                                                  *self._kernel_args, self._base_mass_row)
        acc, lam, x, force, rho = self._solve(t, y)
        a, b = self._rigid_ends
        d_x = x[a, 0] - x[b, 0]
        reaction = (self._base_mass_row @ acc - force[1, 0] - 2.0 * (d_x * (a == 1)) @ lam
                    + 2.0 * (d_x * (b == 1)) @ lam)
        chords = self.chord_rows
        return np.concatenate([[reaction], 2.0 * lam[chords] * rho[self._rigid_chord[chords]]])

    def _ramp_now(self, t):
        """(rho, rho') of every actuator at t, as the right-hand side takes them (the ramp
        extended past its end if ``extend_ramp``)."""
        rho0, rho1, duration = self._kernel_args[1:4]
        if duration == 0.0 or t >= duration > 0.0:
            return rho1, np.zeros_like(rho1)
        duration = abs(duration)
        return rho0 + (max(t, 0.0) / duration) * (rho1 - rho0), (rho1 - rho0) / duration

    def _solve(self, t, y):
        """The equations in numpy: (free accelerations, multipliers, nodes, node forces,
        rho) at (t, y); arrays made once, the KKT system solved by LAPACK's dgesv."""
        rho, rate = self._ramp_now(t)
        k = 4 * self.n
        x, v = self._x, self._v
        x[1, 0], v[1, 0] = rho[0], rate[0]
        x[2:] = y[:k].reshape(-1, 2)
        v[2:] = y[k:].reshape(-1, 2)
        _, jac = self.angle_jacobian(x)
        force = self._loads2 - self._laplacian @ x
        force -= (jac.T @ (self.pivot_damping * (jac @ v.ravel()))).reshape(-1, 2)
        rod = x[2] - x[0]
        force[2] += self.imperfection / (rod @ rod) * np.array([-rod[1], rod[0]])
        a, b = self._rigid_ends
        d, dv = x[a] - x[b], v[a] - v[b]
        chord = self._rigid_chord >= 0
        length = np.where(chord, rho[self._rigid_chord], self._rigid_length)
        length_rate = np.where(chord, rate[self._rigid_chord], 0.0)
        phi = np.einsum('ij,ij->i', d, d) - length * length
        phi_dot = 2.0 * np.einsum('ij,ij->i', d, dv) - 2.0 * length * length_rate
        system = self._system
        for (rows, cols, ends), sign in zip(self._kkt_blocks, (2.0, -2.0)):
            values = sign * d[ends].ravel()
            system[rows, cols] = values
            system[cols, rows] = -values
        rhs = np.concatenate([force.ravel()[4:],
                              -2.0 * np.einsum('ij,ij->i', dv, dv) + 2.0 * length_rate ** 2
                              - 2.0 * BAUMGARTE * phi_dot - BAUMGARTE ** 2 * phi])
        _, _, solution, info = _dgesv(system, rhs)
        if info != 0:
            raise np.linalg.LinAlgError('singular KKT system of the neck')
        return solution[:k], solution[k:], x.copy(), force, rho

    def _for_numpy(self, loads):
        """The numpy evaluation's constant arrays: node buffers, the spring Laplacian, the
        KKT matrix with its mass block, where the constraint rows go in it."""
        self._x, self._v = np.zeros((self.nodes, 2)), np.zeros((self.nodes, 2))
        self._loads2 = np.asarray(loads, dtype=float).reshape(-1, 2)
        laplacian = np.zeros((self.nodes, self.nodes))
        for a, b, k in self.springs:
            laplacian[np.ix_([a, b], [a, b])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        self._laplacian = laplacian
        self._rigid_chord = np.array([-1 if r[3] is None else r[3] for r in self.rigid])
        self._rigid_length = np.array([0.0 if r[2] is None else r[2] for r in self.rigid])
        k, m = 4 * self.n, len(self.rigid)
        self._system = np.zeros((k + m, k + m), order='F')
        self._system[:k, :k] = self.mass
        blocks = []
        for ends in self._rigid_ends:
            which = np.flatnonzero(ends >= 2)
            rows = np.repeat(k + which, 2)
            cols = (2 * (ends[which] - 2)[:, None] + np.arange(2)).ravel()
            blocks.append((rows, cols, which))
        self._kkt_blocks = blocks

    def onset_events(self):
        """One event: the fastest local angle rate crosses ONSET_SPEED (one evaluation of
        the rates per check, not one per angle)."""
        def fastest(t, y):
            return float(np.max(self.rates(t, y)[1] ** 2)) - ONSET_SPEED ** 2
        return [fastest]

    # -- start and rest ------------------------------------------------------------------
    def start_state(self, nodes):
        """Node positions of an equilibrium, at rest in the local angles (as far as the
        moving chords allow: all rates zero when only module 0 moves)."""
        y = np.concatenate([nodes[2:].ravel(), np.zeros(4 * self.n)])
        return self.with_angle_rates(0.0, y, np.zeros(2 * self.n))

    def after_ramp(self, y):
        """At the end of the ramp the actuator velocities step to zero; the local angle
        rates carry on (the module model's convention: rho'' impulses neglected)."""
        t = self.ramp.duration
        return self.with_angle_rates(t, y, self.rates(np.nextafter(t, -np.inf), y)[1])

    def with_angle_rates(self, t, y, target):
        """``y`` with node velocities that satisfy the length constraints at time t and
        give local angle rates as close to ``target`` as they allow (least squares)."""
        y = np.array(y, dtype=float)
        y[4 * self.n:] = 0.0
        x, v, rho, rho_dot = self.full(t, y)
        _, jac = self.angle_jacobian(x)
        rows, _, _ = self.constraint_rows(x, v)
        length, rate = self.lengths(rho, rho_dot)
        b = 2.0 * length * rate - rows[:, :4] @ v.ravel()[:4]
        particular = np.linalg.lstsq(rows[:, 4:], b, rcond=None)[0]
        basis = null_space(rows[:, 4:])
        miss = jac[:, :4] @ v.ravel()[:4] + jac[:, 4:] @ particular - target
        z = np.linalg.lstsq(jac[:, 4:] @ basis, -miss, rcond=None)[0]
        y[4 * self.n:] = particular + basis @ z
        return y

    def _multipliers(self, nodes):
        """The length constraints' multipliers lambda at an equilibrium ``nodes``:
        grad U = lambda . grad(|d|^2 - l^2) on the free coordinates."""
        zero = np.zeros_like(nodes)
        rows, _, _ = self.constraint_rows(nodes, zero)
        gradient = -self.forces(nodes, zero, np.zeros((2 * self.n, 2 * self.nodes)))
        return np.linalg.lstsq(rows[:, 4:].T, gradient[4:], rcond=None)[0]

    def rest_stiffness(self, nodes):
        """The Hessian of L = U - lambda . (|d|^2 - l^2) (the equilibrium ``nodes``'
        multipliers) on the free node coordinates: constant, L being quadratic in them."""
        laplacian = np.zeros((self.nodes, self.nodes))
        pair = np.array([[1.0, -1.0], [-1.0, 1.0]])
        for a, b, k in self.springs:
            laplacian[np.ix_([a, b], [a, b])] += k * pair
        for (a, b, _, _), value in zip(self.rigid, self._multipliers(nodes)):
            laplacian[np.ix_([a, b], [a, b])] -= 2.0 * value * pair
        return np.kron(laplacian, np.eye(2))[4:, 4:]

    def excess_energy(self, nodes, stiffness):
        """Energy (J) above the equilibrium ``nodes`` of states (n, 8N) while rho is held:
        kinetic energy plus L(x) - L(x*) (``stiffness``: :meth:`rest_stiffness`).  L is
        quadratic in the node coordinates and stationary at x*, so that is exactly
        1/2 dx' H_L dx: no cancellation of large energies, and a drift of the rigid
        lengths (the Baumgarte-stabilised constraints hold to ~1e-10 m only) enters to
        second order, not times the chord forces."""
        rest, k = nodes[2:].ravel(), 4 * self.n

        def excess(t, ys):
            delta, v = ys[:, :k] - rest, ys[:, k:]
            return 0.5 * (np.einsum('ni,ij,nj->n', v, self.mass, v)
                          + np.einsum('ni,ij,nj->n', delta, stiffness, delta))
        return excess

    def rest_threshold(self, nodes, stiffness):
        """1/2 SETTLE_TOLERANCE^2 min(h, mu): h and mu the smallest stiffness and inertia
        per unit local angle on the constraints' tangent space at ``nodes``, so that an
        energy below it keeps every angle within the tolerance and every rate below it
        (the module's rule, :meth:`.dynamics.ModuleEquations.settled`, in the same units)."""
        zero = np.zeros_like(nodes)
        basis = null_space(self.constraint_rows(nodes, zero)[0][:, 4:])
        along = self.angle_jacobian(nodes)[1][:, 4:] @ basis       # node motion -> angles
        metric = along.T @ along
        h = eigh(basis.T @ stiffness @ basis, metric, eigvals_only=True)[0]
        mu = eigh(basis.T @ self.mass @ basis, metric, eigvals_only=True)[0]
        return 0.5 * SETTLE_TOLERANCE ** 2 * min(h, mu)

    def slow_angles(self, t, y):
        """The local angles (N*2) of state ``y`` at segment time ``t`` if every local rate
        is below SLOW, else None."""
        angles, rates = self.rates(t, y)
        return None if np.max(np.abs(rates)) > SLOW else np.array(angles, dtype=float)

    def rest_candidate(self, y, known=None):
        """The :class:`~.dynamics.transient.Rest` of the equilibrium a slow state (local rates
        below SLOW, rho held) is settling to, or None (fast, undamped, none found).
        ``known``: a verified equilibrium at rho1 taken if the state is within NEAR of
        it (the quasi-static prediction: no second settle)."""
        if not np.any(self.damping > 0.0):
            return None
        angles = self.slow_angles(self.ramp.duration, y)
        if angles is None:
            return None
        eq = known
        if eq is None or np.max(np.abs(wrap(angles - np.ravel(eq.theta)))) > NEAR:
            end = Stack(tuple(m.with_(rho=r) for m, r in zip(self.modules, self.ramp.rho1)))
            try:
                eq = settle_stack(end, angles.reshape(self.n, 2))
            except (RuntimeError, ValueError):
                return None
        stiffness = self.rest_stiffness(eq.nodes)
        return Rest(theta=eq.theta.ravel(), excess=self.excess_energy(eq.nodes, stiffness),
                    threshold=self.rest_threshold(eq.nodes, stiffness), eq=eq,
                    found_at=angles)

    def settled(self, y):
        """The :class:`~.dynamics.transient.Rest` if the damped energy above the nearby minimum is
        below the least energy of any state outside the tolerance box (linearised), else
        None."""
        return transient.trapped(self.rest_candidate(y), y)


def damping_vector(damping, n):
    """Pivot damping per module (N values) from one value or N."""
    values = np.atleast_1d(np.asarray(damping, dtype=object))
    if values.shape not in ((1,), (n,)):
        raise InvalidParameterError(f'damping must have 1 or {n} values, got {damping!r}')
    return np.broadcast_to([transient.checked_damping(d) for d in values], (n,)).copy()


def _rho_vector(values, n, name):
    values = np.atleast_1d(np.asarray(values, dtype=float))
    if values.shape == (1,):
        values = np.full(n, values[0])
    if values.shape != (n,):
        raise InvalidParameterError(f'{name} must have {n} values (one per module), '
                                    f'got {values.shape}')
    return values


def simulate_neck_snap(stack: Stack, rho_end, rate: float, damping: float, theta_guess,
                       hold: float | None = None,
                       settings: SolverSettings = SolverSettings()) -> NeckSnap:
    """Drive every module's rho from ``stack`` to ``rho_end`` (N values, or one for all)
    at ``rate`` (m/s, the largest change), then hold (``hold`` s, or until settled for
    good, at most MAX_HOLD).  Starts in the stable equilibrium of ``theta_guess`` (N x 2)."""
    transient.checked_hold(hold)
    rho1 = _rho_vector(rho_end, len(stack), 'rho_end')
    end = Stack(tuple(m.with_(rho=float(r)) for m, r in zip(stack.modules, rho1)))
    ramp = RhoRamp(tuple(m.rho for m in stack.modules), tuple(rho1), float(rate))
    system = NeckEquations(stack, ramp, damping)
    start = settle_stack(stack, theta_guess)
    solution, events, rest = transient.run(system, system.start_state(start.nodes), hold,
                                           settings)
    reader = _Reader(system, solution)
    ts = transient.sample_times(solution)
    theta, omega = reader.angles_and_rates(ts)
    shape = (-1, len(stack), 2)
    history = SnapHistory(t=ts, rho=ramp.rho(ts), theta=theta.reshape(shape),
                          theta_dot=omega.reshape(shape), actuator_force=reader.forces(ts))
    onset = min(events) if events else None
    summary = {'onset_rho': None if onset is None else ramp.rho(onset).tolist(),
               'onset_time': onset}
    summary.update(transient.figures(
        ts, reader.angles, reader.rates, reader.forces, onset, rest, ramp.duration,
        energy=None if rest is None else (lambda t: rest.excess(t, solution(t).T))))
    summary['final'] = {'theta': theta[-1].reshape(shape[1:]).tolist(),
                        'speed': float(np.max(np.abs(omega[-1])))}
    track = track_stack(stack, end, start)
    summary.update(_beside_quasi_static(track, rest.theta if rest is not None else theta[-1]))
    return NeckSnap(history=history, summary=summary, quasi_static=track, solution=solution)


class _Reader:
    """Local angles, their rates and the actuator forces of the dense solution at times t."""

    def __init__(self, system, solution):
        self.system, self.solution = system, solution

    def _each(self, t, f):
        t = np.atleast_1d(t)
        return np.array([f(tk, yk) for tk, yk in zip(t, self.solution(t).T)])

    def angles_and_rates(self, t):
        both = self._each(t, lambda tk, yk: np.stack(self.system.rates(tk, yk)))
        return both[:, 0], both[:, 1]

    def angles(self, t):
        return self.angles_and_rates(t)[0]

    def rates(self, t):
        return self.angles_and_rates(t)[1]

    def forces(self, t):
        return self._each(t, self.system.actuator_forces)


def _beside_quasi_static(track, landed):
    """The stack tracker's prediction, and whether inertia lands the neck elsewhere."""
    predicted = track.final.theta.ravel()
    return {'quasi_static': {
                'jumps': [{'kind': j.kind, 'rho': [m.rho for m in j.stack.modules],
                           'theta': np.asarray(j.from_theta).tolist(),
                           'landing': np.asarray(j.to_theta).tolist()} for j in track.jumps],
                'final': {'theta': track.final.theta.tolist()}, 'status': track.status},
            'lands_elsewhere': bool(np.max(np.abs(wrap(landed - predicted))) > SAME_LANDING)}
