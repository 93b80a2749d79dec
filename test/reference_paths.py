"""An independent reference for tracking: the quasi-static path of an overdamped mechanism.

Written for the tests and sharing no code with ``tensegrity_ros.core``.  The mechanism
moves along the straight parameter path p(s) = start + s (end - start) slowly and
heavily damped: at each small step of s the parameters are frozen and the mechanism
slides down its energy (gradient flow d theta/dt = -grad U, integrated with
``scipy.integrate.solve_ivp``) until it rests on a *certified* minimum, then s moves on.

A rest point is certified when Newton from the current point converges to a point
theta* whose Hessian is positive definite with lambda_min > M |theta - theta*|, M a
bound on the third derivatives: the energy is then strictly convex on the ball around
theta* holding theta, so the flow provably ends at theta* (it never leaves that ball).
Everything else is integrated.  A flow that stalls on a saddle is pushed off along the
unstable mode both ways by 1e-7 rad (the lower-energy landing wins, a disagreement is
recorded as ``ambiguous``).

A jump is a step whose displacement is large compared with the motion of the previous
steps and stays finite as the step shrinks: it is bisected in s down to ``JUMP_BRACKET``
(the last s where the mechanism still rests continuously next to its previous state,
and the first s where it lands far away), then the critical point is solved from the
bracket on {grad U = 0, det H = 0} (``scipy.optimize.root``), kept only if it lies in
the bracket.  The landing is the rest point reached by the flow from the last
continuous state with the parameters frozen at the bracket's far end (past a fold,
``LANDING_OFFSET`` further on: the flow through the fold's ghost takes a time
~ 1 / sqrt(s - s*)).

One module: energy, gradient and Hessian written again from docs/model.md section 1.
A neck of N modules (docs/model.md section 4): the 2N local angles, the energy from the
node positions (forward kinematics written here), the N - 1 chord constraints
|A3(i) - A4(i)| = rho(i + 1); the flow is the angle-space gradient projected on the
constraints' tangent space (plus a pull back onto them), rest points are KKT points
with a positive definite reduced Hessian.  Derivatives of the neck: complex-step
gradients (exact to rounding) and central differences of them for the Hessians.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
import math
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

from oracle_solver import oracle_equilibria

TWO_PI = 2.0 * math.pi
#: Width in s of the bracket a jump is bisected to.
JUMP_BRACKET = 1e-9
#: A continuous step moves at most this far (rad, max norm) before it is split.
MAX_STEP_MOTION = 0.02
#: Steps in s: first and largest, and the smallest before a suspicious step is bisected.
FIRST_STEP = 1.0 / 128
MAX_STEP = 1.0 / 64
MIN_STEP = 1e-6
#: Landing past a branch point (where the flow stalls on the saddle) is computed this
#: far past the bracket in s (the landing state moves continuously with s).
LANDING_OFFSET = 1e-6
#: A jump lands at least this far (rad, max norm) from the last continuous state.
JUMP_DISTANCE = 1e-5
#: A critical point whose soft mode is this nearly orthogonal to dG/ds (see
#: ``mode_alignment``) may be a branch point passed continuously: worth checking.
#: (A perfect pitchfork's bisected departure carries ~1e-7 rad of rounding-amplified
#: asymmetry, so ``classify``'s 1e-6 can call it a fold.)
PASSAGE_ALIGNMENT = 1e-3
#: A branch point is passed continuously (supercritical) when the flow frozen
#: PASSAGE_SHRINK times closer to it rests sqrt(PASSAGE_SHRINK) times closer to the
#: departure (the buckled minima grow like sqrt(s - s*)); accepted within this factor.
PASSAGE_SHRINK = 16.0
PASSAGE_SLACK = 1.6
#: Push-off from a saddle along its unstable mode (rad).
PUSH_OFF = 1e-7
#: A flow is close to its rest point (see ``rest_certified``) when its force (relative
#: to the energy scale) is below CLOSE_FORCE and Newton's minimum is within
#: CLOSE_DISTANCE (rad, max norm).
CLOSE_FORCE = 1e-5
CLOSE_DISTANCE = 1e-3
#: A flow leg stops when a chord constraint's gradient falls below this (relative to a
#: rod length): a module close to a change point of its linkage (see
#: ``NeckSystem.change_point_branches``); the flow is pushed this far (rad) past it.
CHANGE_POINT_GRADIENT = 1e-2
CHANGE_POINT_PUSH = 1e-4
#: Absolute tolerance (rad) of a flow leg's integration (the rest point itself is then
#: certified by Newton, so this only has to keep the flow in its basin).
FLOW_ATOL = 1e-11
#: Longest flow (in units of the stiffest relaxation time) before the reference gives up.
MAX_FLOW_TIME = 1e18
#: Budgets: flow legs per rest, steps per path (the reference says so rather than hang).
MAX_LEGS = 200
MAX_STEPS = 3000
#: Work budget of one reference path (:func:`quasi_static_path`) or of one flow called
#: on its own: evaluations of the flows' velocity and Jacobian (the integrator's work; a
#: neck's cost ~0.24 ms each here).  Past it the reference raises :class:`Undecided`
#: instead of integrating on: issue 30's run of the N = 3 chord ramp with fx 1e-4 sat in
#: one flow leg until pytest's 600 s timeout.  The default run's paths use 2.2e5 at most
#: (that path, ~50 s; Haswell kernel), FULL_NECKS' slowest about twice that; 1e6 ends an
#: undecided one within ~4 min.
MAX_EVALUATIONS = 1_000_000

FIELDS = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')


def wrap(theta):
    return (np.asarray(theta, dtype=float) + math.pi) % TWO_PI - math.pi


def angle_distance(a, b):
    """Max-norm distance of two angle vectors on the torus."""
    return float(np.max(np.abs(wrap(np.asarray(a, dtype=float) - np.asarray(b, dtype=float)))))


def values_of(params):
    """The 12 parameter values of a public ``ModuleParams`` (read by attribute)."""
    return np.array([float(getattr(params, name)) for name in FIELDS]), float(params.g)


# -- one module (docs/model.md section 1) -----------------------------------------------------

@dataclass(frozen=True)
class Point:
    """One module's parameters at one s, rod weights folded into the nodal loads."""

    rho: float
    L1: float
    L2: float
    ka: float
    kb: float
    kc: float
    f3x: float
    f3y: float
    f4x: float
    f4y: float

    @classmethod
    def from_values(cls, v, g):
        rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y, m1, m2 = (float(x) for x in v)
        return cls(rho, L1, L2, ka, kb, kc, f3x, f3y - 0.5 * m1 * g, f4x, f4y - 0.5 * m2 * g)


def module_energy(p, t):
    a3 = np.array([p.L1 * math.cos(t[0]), p.L1 * math.sin(t[0])])
    a4 = np.array([p.rho - p.L2 * math.cos(t[1]), p.L2 * math.sin(t[1])])
    a2 = np.array([p.rho, 0.0])
    return (0.5 * p.ka * np.sum((a3 - a2) ** 2) + 0.5 * p.kb * np.sum(a4 ** 2)
            + 0.5 * p.kc * np.sum((a4 - a3) ** 2)
            - (p.f3x * a3[0] + p.f3y * a3[1] + p.f4x * a4[0] + p.f4y * a4[1]))


def module_gradient(p, t):
    s1, c1, s2, c2 = math.sin(t[0]), math.cos(t[0]), math.sin(t[1]), math.cos(t[1])
    s12 = math.sin(t[0] + t[1])
    return np.array([
        p.L1 * ((p.ka + p.kc) * p.rho * s1 - p.kc * p.L2 * s12 + p.f3x * s1 - p.f3y * c1),
        p.L2 * ((p.kb + p.kc) * p.rho * s2 - p.kc * p.L1 * s12 - p.f4x * s2 - p.f4y * c2)])


def module_hessian(p, t):
    s1, c1, s2, c2 = math.sin(t[0]), math.cos(t[0]), math.sin(t[1]), math.cos(t[1])
    c12 = math.cos(t[0] + t[1])
    h12 = -p.kc * p.L1 * p.L2 * c12
    return np.array([
        [p.L1 * ((p.ka + p.kc) * p.rho * c1 - p.kc * p.L2 * c12 + p.f3x * c1 + p.f3y * s1), h12],
        [h12, p.L2 * ((p.kb + p.kc) * p.rho * c2 - p.kc * p.L1 * c12 - p.f4x * c2 + p.f4y * s2)]])


def module_third_derivative_bound(p):
    """M with ||H(a) - H(b)||_2 <= M |a - b|_2: every Hessian entry is a sum of
    sines/cosines of t1, t2 or t1 + t2 (gradient norm <= sqrt 2) with known coefficients."""
    c11 = p.L1 * ((p.ka + p.kc) * p.rho + p.kc * p.L2 + abs(p.f3x) + abs(p.f3y))
    c22 = p.L2 * ((p.kb + p.kc) * p.rho + p.kc * p.L1 + abs(p.f4x) + abs(p.f4y))
    c12 = p.kc * p.L1 * p.L2
    return math.sqrt(2.0) * math.sqrt(c11 ** 2 + c22 ** 2 + 2.0 * c12 ** 2)


class ModuleSystem:
    """One module along a straight parameter path (ModuleParams start -> end)."""

    def __init__(self, start, end=None):
        self.v0, self.g = values_of(start)
        v1, _ = values_of(start if end is None else end)
        self.dv = v1 - self.v0
        self._last = None

    def point(self, s):
        """The parameters at s (the last one kept: a flow evaluates one s many times)."""
        if self._last is None or self._last[0] != s:
            self._last = (s, Point.from_values(self.v0 + s * self.dv, self.g))
        return self._last[1]

    def energy(self, t, s):
        return module_energy(self.point(s), t)

    def gradient(self, t, s):
        return module_gradient(self.point(s), t)

    def hessian(self, t, s):
        return module_hessian(self.point(s), t)

    def rate(self, s):
        return module_third_derivative_bound(self.point(s))

    def residual_scale(self, s):
        return self.rate(s)

    def start_state(self, theta):
        return np.asarray(theta, dtype=float).copy()

    def angles(self, t):
        return wrap(t)

    def velocity(self, t, s):
        return -self.gradient(t, s) / self.rate(s)

    def velocity_jacobian(self, t, s):
        return -self.hessian(t, s) / self.rate(s)

    def force(self, t, s):
        """|grad U| relative to the energy scale."""
        return float(np.linalg.norm(self.gradient(t, s))) / self.rate(s)

    def critical_point(self, t, s, iterations=60):
        """Newton on grad U = 0 from t: (point, converged).  Converged means the Newton
        step itself is at rounding level (a small gradient alone is not enough where the
        Hessian is nearly singular)."""
        t = np.array(t, dtype=float)
        scale = self.residual_scale(s)
        for _ in range(iterations):
            g = self.gradient(t, s)
            try:
                step = np.linalg.solve(self.hessian(t, s), g)
            except np.linalg.LinAlgError:
                return t, False
            if not np.all(np.isfinite(step)) or np.max(np.abs(step)) > 0.5:
                return t, False
            t = t - step
            if np.max(np.abs(step)) < 1e-14 + rounding_radius(self, t, s):
                return t, bool(np.max(np.abs(self.gradient(t, s))) <= 1e-11 * scale)
        return t, False

    def stability(self, t, s):
        """Ascending eigenvalues and modes (columns) of the Hessian."""
        return np.linalg.eigh(self.hessian(t, s))

    def certified_rest(self, t, s, close=False):
        """The minimum the flow from t provably ends at, or None (see the module docstring)."""
        star, ok = self.critical_point(t, s)
        if not ok:
            return None
        low = np.linalg.eigvalsh(self.hessian(star, s))[0]
        return star if rest_certified(self, t, s, star, low, self.rate(s), close) else None

    def on_saddle(self, t, s):
        return stalled_on_saddle(self, t, s)

    def critical_residual(self, z):
        """{grad U = 0, det H = 0} in (t1, t2, s), scaled."""
        t, s = z[:2], z[2]
        scale = self.rate(s)
        return np.concatenate([self.gradient(t, s) / scale,
                               [np.linalg.det(self.hessian(t, s)) / scale ** 2]])

    def singular_chord(self, t, s):
        """One module has no chord constraint (see :meth:`NeckSystem.singular_chord`)."""
        return 1.0

    def change_point_branches(self, t, s, opened=False):
        return None

    def energy_seen_from(self, star, t, s):
        """The energy at t compared with the minimum star's (no constraints: U itself)."""
        return self.energy(t, s)

    def is_stable_equilibrium(self, t, s, tol=1e-8):
        """Gradient ~ 0 (relative) and Hessian positive definite, by this reference."""
        scale = self.rate(s)
        low = np.linalg.eigvalsh(self.hessian(t, s))[0]
        return bool(np.max(np.abs(self.gradient(t, s))) <= tol * scale and low > 0)


# -- the neck (docs/model.md section 4) ---------------------------------------------------------

class NeckSystem:
    """N stacked modules in their 2N local angles with N - 1 chord constraints.

    ``start``/``end`` are sequences of ``ModuleParams`` (bottom to top).  A lower
    module's A3A4 spring is kept (it is in parallel with the rigid chord: a constant
    energy on the constraint set, no effect on equilibria or stability)."""

    COMPLEX_STEP = 1e-30
    FD_STEP = 1e-5

    def __init__(self, start, end=None):
        end = start if end is None else end
        pairs = [values_of(m) for m in start]
        self.g = pairs[0][1]
        self.v0 = np.array([v for v, _ in pairs])
        self.dv = np.array([values_of(m)[0] for m in end]) - self.v0
        self.n = len(start)
        self._last = None

    def values(self, s):
        return self.v0 + s * self.dv

    def nodes(self, theta, s):
        """A1, A2, A3, A4 of every module, base frame: arrays (batch, N, 4, 2) (complex ok)."""
        theta = np.asarray(theta)
        batch = theta.reshape(-1, self.n, 2)
        v = self.values(s)
        dtype = np.result_type(batch.dtype, float)
        out = np.zeros((batch.shape[0], self.n, 4, 2), dtype=dtype)
        a1x = a1y = a2y = np.zeros(batch.shape[0], dtype=dtype)
        a2x = np.full(batch.shape[0], v[0, 0], dtype=dtype)
        for i in range(self.n):
            dx, dy = a2x - a1x, a2y - a1y
            norm = np.sqrt(dx * dx + dy * dy)
            ex, ey = dx / norm, dy / norm             # base direction; its normal (-ey, ex)
            c1, s1 = np.cos(batch[:, i, 0]), np.sin(batch[:, i, 0])
            c2, s2 = np.cos(batch[:, i, 1]), np.sin(batch[:, i, 1])
            L1, L2 = v[i, 1], v[i, 2]
            a3x, a3y = a1x + L1 * (c1 * ex - s1 * ey), a1y + L1 * (c1 * ey + s1 * ex)
            a4x, a4y = a2x + L2 * (-c2 * ex - s2 * ey), a2y + L2 * (-c2 * ey + s2 * ex)
            for k, (x, y) in enumerate(((a1x, a1y), (a2x, a2y), (a3x, a3y), (a4x, a4y))):
                out[:, i, k, 0], out[:, i, k, 1] = x, y
            a1x, a1y, a2x, a2y = a4x, a4y, a3x, a3y
        return out

    def _energy_of(self, x, v):
        sq = lambda d: d[..., 0] ** 2 + d[..., 1] ** 2      # noqa: E731
        a1, a2, a3, a4 = x[:, :, 0], x[:, :, 1], x[:, :, 2], x[:, :, 3]
        ka, kb, kc = v[:, 3], v[:, 4], v[:, 5]
        springs = 0.5 * (ka * sq(a3 - a2) + kb * sq(a4 - a1) + kc * sq(a4 - a3))
        loads = (v[:, 6] * a3[..., 0] + v[:, 7] * a3[..., 1]
                 + v[:, 8] * a4[..., 0] + v[:, 9] * a4[..., 1])
        weights = 0.5 * self.g * (v[:, 10] * (a1[..., 1] + a3[..., 1])
                                  + v[:, 11] * (a2[..., 1] + a4[..., 1]))
        return np.sum(springs - loads + weights, axis=1)

    @staticmethod
    def _chords_of(x, v):
        """(|A3(i) - A4(i)|^2 - rho(i+1)^2) / (2 rho(i+1)), i < N - 1: (batch, N - 1)."""
        d = x[:, :-1, 2] - x[:, :-1, 3]
        rho = v[1:, 0]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 - rho ** 2) / (2.0 * rho)

    def energy(self, theta, s):
        x = self.nodes(np.asarray(theta, dtype=float)[None], s)
        return float(self._energy_of(x, self.values(s))[0])

    def constraints(self, theta, s):
        return self._complex_step(theta, s)[2]

    def _complex_step(self, theta, s):
        """(grad U, constraint Jacobian (N-1, 2N), constraints) by complex steps (the
        real parts are the values to rounding); the last point's are kept."""
        theta = np.asarray(theta, dtype=float)
        key = (theta.tobytes(), s)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        m = theta.size
        probe = theta[None, :] + 1j * self.COMPLEX_STEP * np.eye(m)
        x, v = self.nodes(probe, s), self.values(s)
        chords = self._chords_of(x, v)
        result = (self._energy_of(x, v).imag / self.COMPLEX_STEP,
                  chords.imag.T / self.COMPLEX_STEP, chords[0].real.copy())
        self._last = (key, result)
        return result

    def gradient(self, theta, s):
        return self._complex_step(theta, s)[0]

    def constraint_jacobian(self, theta, s):
        return self._complex_step(theta, s)[1]

    def lagrangian_gradient(self, theta, mu, s):
        grad, jac, _ = self._complex_step(theta, s)
        return grad + jac.T @ mu

    def lagrangian_hessian(self, theta, mu, s):
        """Central differences (step FD_STEP) of the complex-step Lagrangian gradient, all
        2 x 2N x 2N probes in one batch through the forward kinematics."""
        theta = np.asarray(theta, dtype=float)
        m, h = theta.size, self.FD_STEP
        shifts = np.concatenate([h * np.eye(m), -h * np.eye(m)])           # (2m, m)
        probe = (theta + shifts)[:, None, :] + 1j * self.COMPLEX_STEP * np.eye(m)[None]
        x, v = self.nodes(probe.reshape(-1, m), s), self.values(s)
        grads = (self._energy_of(x, v).imag / self.COMPLEX_STEP).reshape(2 * m, m)
        chords = (self._chords_of(x, v).imag / self.COMPLEX_STEP).reshape(2 * m, m, -1)
        lagrangian = grads + chords @ np.asarray(mu, dtype=float)
        w = (lagrangian[:m] - lagrangian[m:]) / (2 * h)
        return 0.5 * (w + w.T)

    def rate(self, s):
        """An energy scale (J): stiffness times length squared plus load times length."""
        v = self.values(s)
        length = float(np.max(v[:, 1:3]))
        load = float(np.max(np.abs(v[:, 6:10]))) + 0.5 * self.g * float(np.max(v[:, 10:12]))
        return float(np.max(v[:, 3:6])) * length ** 2 + load * length

    def residual_scale(self, s):
        return self.rate(s)

    def start_state(self, theta):
        return np.asarray(theta, dtype=float).ravel().copy()

    def angles(self, t):
        return wrap(t).reshape(self.n, 2)

    def multipliers(self, theta, s):
        grad, jac, _ = self._complex_step(theta, s)
        if jac.shape[0] == 0:
            return np.zeros(0)
        return -np.linalg.lstsq(jac.T, grad, rcond=None)[0]

    def velocity(self, theta, s):
        grad, jac, _ = self._complex_step(theta, s)
        rate = self.rate(s)
        if jac.shape[0] == 0:
            return -grad / rate
        gram = jac @ jac.T
        tangential = grad - jac.T @ np.linalg.solve(gram, jac @ grad)
        pull = jac.T @ np.linalg.solve(gram, self.constraints(theta, s))
        return -tangential / rate - 10.0 * pull

    def velocity_jacobian(self, theta, s):
        """The flow's Jacobian up to terms that vanish at equilibria (enough for the
        implicit integrator's Newton iterations)."""
        mu = self.multipliers(theta, s)
        w = self.lagrangian_hessian(theta, mu, s)
        jac = self.constraint_jacobian(theta, s)
        if jac.shape[0] == 0:
            return -w / self.rate(s)
        normal = jac.T @ np.linalg.solve(jac @ jac.T, jac)
        tangent = np.eye(len(theta)) - normal
        return -tangent @ w @ tangent / self.rate(s) - 10.0 * normal

    def force(self, theta, s):
        """Projected |grad U| relative to the energy scale, plus the constraint violation."""
        grad, jac, _ = self._complex_step(theta, s)
        if jac.shape[0]:
            grad = grad - jac.T @ np.linalg.solve(jac @ jac.T, jac @ grad)
        violation = float(np.linalg.norm(self.constraints(theta, s)))
        return float(np.linalg.norm(grad)) / self.rate(s) + violation

    def _kkt(self, z, s):
        m = 2 * self.n
        theta, mu = z[:m], z[m:]
        grad, jac, _ = self._complex_step(theta, s)
        return np.concatenate([grad + jac.T @ mu, self.constraints(theta, s)]), jac

    def critical_point(self, theta, s, iterations=60):
        """Newton on the KKT system from theta: (theta*, converged), converged meaning
        a Newton step at rounding level (see :meth:`ModuleSystem.critical_point`)."""
        m = 2 * self.n
        z = np.concatenate([np.asarray(theta, dtype=float), self.multipliers(theta, s)])
        scale = self.rate(s)
        for _ in range(iterations):
            f, jac = self._kkt(z, s)
            w = self.lagrangian_hessian(z[:m], z[m:], s)
            k = np.block([[w, jac.T], [jac, np.zeros((len(z) - m, len(z) - m))]])
            try:
                step = np.linalg.solve(k, f)
            except np.linalg.LinAlgError:
                return z[:m], False
            if not np.all(np.isfinite(step)) or np.max(np.abs(step[:m])) > 0.5:
                return z[:m], False
            z = z - step
            undefined = self.chord_rounding_radius(z[:m], s)
            if np.max(np.abs(step[:m])) < 1e-13 + rounding_radius(self, z[:m], s) + undefined:
                f, _ = self._kkt(z, s)
                # a point within the chords' rounding radius of the KKT point has a residual
                # up to |W| times that radius: next to a flat crossing (the N = 3 neck's
                # module 0 4e-7 rad from it, mu ~ 7.5e6 N, |W| ~ 3e4 J/rad^2, radius 2e-9
                # rad) Newton cycles with a residual ~1e-7, far above 1e-10 of the scale
                slack = float(np.linalg.norm(w, 2)) * undefined
                if np.max(np.abs(f[:m])) <= 1e-10 * scale + slack \
                        and np.max(np.abs(f[m:]), initial=0.0) <= 1e-12:
                    return z[:m], True
                # (else iterate on: with a large radius the stop may come before the residual
                # is down, where the plain threshold had gone on: seed 0 stream 9's start,
                # module 0 3e-8 rad from its crossing, radius 8e-8)
        return z[:m], False

    def chord_rounding_radius(self, theta, s):
        """How far (rad) the chord constraints fix a point at all: their rounding error
        (~1e-16 of a length) over the constraint Jacobian's smallest singular value.
        Next to a module's flat crossing that value is tiny (its chord's gradient in its
        own angles ~0) and Newton's steps stall at this level, above rounding_radius's:
        2.7e-13 rad 3e-4 rad from the crossing (config/neck.yaml, bench_round_commands
        seed 0 stream 8, joint_commands {0: 0.13, 1: 0.12, 2: 0.15}), so every Newton
        solve on the continued minimum 'failed' and the reference reported a false fold
        at s = 1 - 2.4e-7 (the minimum goes on, stable, to the command's end)."""
        jac = self.constraint_jacobian(theta, s)
        if jac.shape[0] == 0:
            return 0.0
        low = float(np.linalg.svd(jac, compute_uv=False)[-1])
        return 1e-15 * float(np.max(self.values(s)[:, 1:3])) / max(low, 1e-300)

    def reduced(self, theta, s):
        """(reduced Hessian, null-space basis Z) at a feasible theta."""
        mu = self.multipliers(theta, s)
        w = self.lagrangian_hessian(theta, mu, s)
        jac = self.constraint_jacobian(theta, s)
        if jac.shape[0] == 0:
            return w, np.eye(w.shape[0])
        _, _, vt = np.linalg.svd(jac)
        z = vt[jac.shape[0]:].T
        return z.T @ w @ z, z

    def stability(self, theta, s):
        r, z = self.reduced(theta, s)
        values, vectors = np.linalg.eigh(r)
        return values, z @ vectors

    def certified_rest(self, theta, s, close=False):
        """KKT point next to theta with a positive definite reduced Hessian, close enough
        that the flow ends there: lambda_min > M |theta - theta*| with M a generous
        bound (4 N times the energy scale) on the third derivatives."""
        star, ok = self.critical_point(theta, s)
        if not ok:
            return None
        low = np.linalg.eigvalsh(self.reduced(star, s)[0])[0]
        return star if rest_certified(self, theta, s, star, low, 4.0 * self.n * self.rate(s),
                                      close) else None

    def on_saddle(self, theta, s):
        return stalled_on_saddle(self, theta, s)

    def critical_residual(self, z):
        """{KKT = 0, det(reduced Hessian) = 0} in (theta, mu, s), scaled."""
        m = 2 * self.n
        s = z[-1]
        scale = self.rate(s)
        f, _ = self._kkt(z[:-1], s)
        r, _ = self.reduced(z[:m], s)
        det = np.linalg.det(r / scale)
        return np.concatenate([f[:m] / scale, f[m:], [det]])

    def singular_chord(self, theta, s):
        """The smallest chord-constraint gradient over a length, each in its own module's
        two angles: ~0 where a module lies flat at a change point of its linkage (see
        :meth:`change_point_branches`).  (Chord i also moves with the lower modules' angles,
        through its base, the chord below: that part is a multiple of the row below, so it
        hides the rank loss from the full row's norm.)"""
        own = self._own_chord_gradients(theta, s)
        if own.size == 0:
            return 1.0
        return float(np.min(own)) / float(np.max(self.values(s)[:, 1:3]))

    def _own_chord_gradients(self, theta, s):
        """|d chord_i / d (module i's angles)| for each chord constraint i."""
        jac = self.constraint_jacobian(theta, s)
        return np.array([np.linalg.norm(jac[i, 2 * i:2 * i + 2]) for i in range(jac.shape[0])])

    def _module_chord(self, i, theta, angles, s):
        """Module i's chord constraint as a function of its own two angles, the other
        modules held at ``theta`` (the chord is in the module's own frame: its base, the
        chord below, and its rods)."""
        probe = np.array(theta, dtype=float)
        probe[2 * i:2 * i + 2] = angles
        return self.constraints(probe, s)[i]

    def change_point_branches(self, theta, s, push=CHANGE_POINT_PUSH, opened=False):
        """(crossing, [states]) where module i lies flat at a change point of its linkage.

        With equal rods and equal chords a module is a parallelogram linkage: flat, its
        chord constraint has a zero gradient and its solution set crosses itself (the
        parallelogram and the anti-parallelogram modes, like a four-bar's change point).
        The constrained flow stalls there (the projection on the constraints is undefined).
        The mechanism goes on along one of the four half-branches leaving the crossing:
        returned as states ``push`` rad out along each, put back on the constraint by a
        Newton step along its gradient.  None if no module is at a crossing.

        ``opened``: also where the chord's saddle point lies off the constraint (the
        crossing opened into two branches, as a chord ramp carries the module past flat):
        then the two states of the branches nearest the saddle point (where a flow kept
        mirror-symmetric to the last bit stalls: the projection is undefined there)."""
        theta = np.asarray(theta, dtype=float)
        own = self._own_chord_gradients(theta, s)
        if own.size == 0:
            return None
        i = int(np.argmin(own))
        chord = lambda a: self._module_chord(i, theta, a, s)       # noqa: E731
        h = 1e-5

        def gradient(a):
            return np.array([(chord(a + h * e) - chord(a - h * e)) / (2 * h) for e in np.eye(2)])

        def hessian(a):
            cols = [(gradient(a + h * e) - gradient(a - h * e)) / (2 * h) for e in np.eye(2)]
            w = np.array(cols)
            return 0.5 * (w + w.T)

        with np.errstate(all='ignore'):
            sol = root(gradient, theta[2 * i:2 * i + 2], tol=1e-13)
        length = float(np.max(self.values(s)[:, 1:3]))
        # (the solver's own success flag is not asked: near the root the difference
        # quotients are rounding-limited; the residuals below are what counts)
        offset = chord(sol.x)
        if np.max(np.abs(gradient(sol.x))) > 1e-7 * length \
                or abs(offset) > (1e-3 if opened else 1e-9) * length \
                or angle_distance(sol.x, theta[2 * i:2 * i + 2]) > 0.1:
            return None
        values, vectors = np.linalg.eigh(hessian(sol.x))
        if values[0] >= 0 or values[1] <= 0:
            return None
        crossing = theta.copy()
        crossing[2 * i:2 * i + 2] = sol.x

        def on_chord(a):
            """The crossing with module i's angles a, first put back onto its chord
            constraint (five Newton steps along the constraint's gradient)."""
            for _ in range(5):
                g = gradient(a)
                a = a - chord(a) * g / float(g @ g)
            state = crossing.copy()
            state[2 * i:2 * i + 2] = a
            return state

        if abs(offset) > 1e-9 * length:         # opened: offset + values . (u, v)^2 / 2 = 0
            k = 1 if offset < 0 else 0
            across = vectors[:, k] * math.sqrt(-2.0 * offset / values[k])
            return crossing, [on_chord(sol.x + way * across) for way in (1.0, -1.0)]
        states = []
        for sign in (1.0, -1.0):
            direction = (math.sqrt(values[1]) * vectors[:, 0]
                         + sign * math.sqrt(-values[0]) * vectors[:, 1])
            direction /= np.linalg.norm(direction)
            states += [on_chord(sol.x + way * push * direction) for way in (1.0, -1.0)]
        return crossing, states

    def energy_seen_from(self, star, theta, s):
        """The energy at theta put back on the constraints at s (the shortest way: min-norm
        Gauss-Newton steps), to compare with the constrained minimum star's.  U alone
        moves to first order off the constraint set (the chord forces): a state rested
        at a nearby s lies ~1e-7 off it after a 1e-7 step in s, its U then differs by
        ~mu 1e-7 (3.7e-6 J next to the N = 3 chord ramp's fold), more than the minimum's
        own energy drop.  The Lagrangian U + mu* . c at theta (mu* star's multipliers)
        removes that first-order term but not the second-order one, mu* c'' d^2 / 2 over
        the distance d off the constraints: next to a module's flat crossing mu* is huge
        (the chord's gradient ~0) and c'' indefinite, and the Lagrangian put y_a 1.3e-4 J
        below the minimum it continues to (config/neck.yaml, bench_round_commands seed 0
        stream 7, mu* ~ -6000 N: the bisection then lost the fold at s = 0.5 + 2.2e-10).
        Put back on the constraints, U is compared where star's is (the Lagrangian term
        stays for what the projection leaves, ~rounding)."""
        theta = self.projected(theta, s)
        mu = self.multipliers(star, s)
        return self.energy(theta, s) + float(mu @ self.constraints(theta, s))

    def projected(self, theta, s, steps=8):
        """theta moved onto the chord constraints at s by min-norm Gauss-Newton steps
        (theta itself if they do not converge: the caller's comparison is then first-order)."""
        theta = np.array(theta, dtype=float)
        tol = 1e-15 * float(np.max(self.values(s)[:, 1:3]))
        y = theta
        for _ in range(steps):
            c = self.constraints(y, s)
            if c.size == 0 or np.max(np.abs(c)) <= tol:
                return y
            y = y - np.linalg.lstsq(self.constraint_jacobian(y, s), c, rcond=None)[0]
        c = self.constraints(y, s)
        return y if np.max(np.abs(c)) <= 1e3 * tol and angle_distance(y, theta) < CLOSE_DISTANCE \
            else theta

    def is_stable_equilibrium(self, theta, s, tol=1e-8):
        theta = np.asarray(theta, dtype=float).ravel()
        mu = self.multipliers(theta, s)
        scale = self.rate(s)
        stationary = np.max(np.abs(self.lagrangian_gradient(theta, mu, s))) <= tol * scale
        feasible = np.max(np.abs(self.constraints(theta, s)), initial=0.0) <= tol * 1e2
        low = np.linalg.eigvalsh(self.reduced(theta, s)[0])[0]
        return bool(stationary and feasible and low > 0)


# -- the overdamped flow and the quasi-static path ----------------------------------------

def rounding_radius(system, y, s):
    """How far a critical point is defined at all: the gradient's rounding error
    (~1e-14 of the energy scale) over the smallest |eigenvalue| of the stability matrix.
    Closer than this, no flow and no Newton step can tell positions apart."""
    values, _ = system.stability(y, s)
    return 1e-14 * system.rate(s) / max(float(np.min(np.abs(values))), 1e-300)


def rest_certified(system, y, s, star, low, bound, close=False):
    """Whether the flow from y ends at the minimum star (lambda_min ``low`` > 0).

    Proved when lambda_min > M |y - star| (``bound`` = M; the energy is then convex on
    a ball around star holding y) or y is star to rounding.  Near a degenerate minimum
    that ball is tiny and the flow relaxes slowly (time ~ 1 / lambda_min), so a flow
    that has come close is also accepted: its force is small, star is within
    ``CLOSE_DISTANCE``, lower in energy, and the flow heads for it (the velocity points
    at star: off a saddle's side, or past a fold's ghost, it points elsewhere)."""
    if low <= 0:
        return False
    r = float(np.linalg.norm(star - y))
    if low > bound * r or r <= rounding_radius(system, star, s):
        return True
    if system.force(y, s) > CLOSE_FORCE or angle_distance(star, y) > CLOSE_DISTANCE:
        return False
    if system.energy(star, s) > system.energy_seen_from(star, y, s) + 1e-13 * system.rate(s):
        return False
    v = system.velocity(y, s)
    return float(v @ (star - y)) >= 0.9 * float(np.linalg.norm(v)) * r


def stalled_on_saddle(system, y, s):
    """(saddle, unstable mode) if y lies on a saddle's stable set (numerically: no
    component along the unstable mode), where the flow would stall; else None."""
    star, ok = system.critical_point(y, s)
    if not ok or np.linalg.norm(star - y) > 1e-3:
        return None
    values, modes = system.stability(star, s)
    if values[0] >= 0:
        return None
    offset = abs(float(modes[:, 0] @ (y - star)))
    if offset <= 1e-9 * float(np.linalg.norm(y - star)) + 1e-14:
        return star, modes[:, 0]
    return None


class NoRest(RuntimeError):
    """The flow did not come to a certified rest within ``MAX_FLOW_TIME``."""


class Undecided(RuntimeError):
    """The reference spent its work budget (``MAX_EVALUATIONS``) without deciding: not a
    result about the mechanism, and never taken for one (not a :class:`NoRest`, which
    the reference's own decisions catch)."""


class _Work:
    """Evaluations spent by the flows of the outermost reference call under way."""

    spent = 0
    limit = None
    deadline = None         # (CPU seconds, process_time) where a caller set one


@contextmanager
def work_budget(limit=None, seconds=None):
    """The budget of a reference call: opened by the outermost one, shared by the calls
    nested in it (``limit``: MAX_EVALUATIONS by default; ``seconds``: CPU time too, where
    given: an evaluation count alone bounds the time poorly, 53 s on 39 651 of them)."""
    if _Work.limit is not None:
        yield
        return
    _Work.spent, _Work.limit = 0, MAX_EVALUATIONS if limit is None else limit
    _Work.deadline = None if seconds is None else (seconds, time.process_time() + seconds)
    try:
        yield
    finally:
        _Work.limit = _Work.deadline = None


def spend(what, s):
    """Count one evaluation of a flow; :class:`Undecided` past the budget."""
    _Work.spent += 1
    if _Work.limit is not None and _Work.spent > _Work.limit:
        raise Undecided(f'the reference spent its budget of {_Work.limit} evaluations '
                        f'({what} at s={s!r}) without deciding')
    if _Work.deadline is not None and _Work.spent % 256 == 0 and (
            time.process_time() > _Work.deadline[1]):
        raise Undecided(f'the reference spent its budget of {_Work.deadline[0]:g} s of CPU '
                        f'({what} at s={s!r}) without deciding')


def evaluations_spent():
    """Evaluations spent by the last (or the current) outermost reference call."""
    return _Work.spent


@dataclass
class Rest:
    state: np.ndarray
    ambiguous: bool = False
    #: Where the other ways out of a saddle (the lower energy wins) or of a change point
    #: (the steepest half-branch wins) land.
    alternatives: list = field(default_factory=list)


class Stalled(RuntimeError):
    """The flow stalled on a saddle's stable set and push-offs were not asked for."""


def flow_to_rest(system, y0, s, push_offs=2, anchor=None, close=False) -> Rest:
    """Where the overdamped mechanism released at y0 (parameters frozen at s) comes to rest
    (within the work budget: :func:`work_budget`).

    Integrated in legs, each ending when the (relative) force has fallen tenfold or the
    leg's time is up; after each leg the rest point is certified if possible.  Each leg
    integrates the displacement from an anchor (the leg's start, or the saddle pushed
    off from), so that tolerances are relative to the motion itself: a slow escape from
    a nearly degenerate saddle is resolved, not damped away by large implicit steps."""
    with work_budget():
        return _flow_to_rest(system, y0, s, push_offs, anchor, close)


def _flow_to_rest(system, y0, s, push_offs, anchor, close):
    y = np.array(y0, dtype=float)
    chunk, elapsed = 1.0, 0.0
    for _ in range(MAX_LEGS):
        star = system.certified_rest(y, s, close)
        if star is not None:
            return Rest(star)
        stalled = system.on_saddle(y, s)
        if stalled is not None:
            if push_offs <= 0:
                raise Stalled(f'stalled on a saddle at s={s!r}')
            return _push_off(system, *stalled, s, push_offs)
        target = 0.1 * system.force(y, s)
        if target < 1e-14 and elapsed == 0.0 and anchor is None:   # at rest to rounding
            values, modes = system.stability(y, s)
            if values[0] > 0:
                return Rest(y)
            if push_offs <= 0:
                raise Stalled(f'stalled on a saddle at s={s!r}')
            return _push_off(system, y, modes[:, 0], s, push_offs)
        if elapsed > MAX_FLOW_TIME:
            raise NoRest(f'no certified rest at s={s!r} from {y0} after t={elapsed:g}')
        base = y if anchor is None else anchor
        # tolerances relative to the state (rad), or to the motion off a saddle: the
        # displacement of a leg is ~0 at its start, so an absolute 1e-14 on it would
        # cap the steps through a fold's ghost (flows of ~1e9 relaxation times)
        atol = FLOW_ATOL if anchor is None else 1e-10 * float(np.max(np.abs(y - anchor)))
        anchor = None
        weaker = lambda _, x: system.force(base + x, s) - target      # noqa: E731
        weaker.terminal, weaker.direction = True, -1
        level = _flat_level(system, y, s)
        flat = lambda _, x: system.singular_chord(base + x, s) - level    # noqa: E731
        flat.terminal, flat.direction = True, -1
        sol = solve_ivp(lambda _, x: _velocity(system, base + x, s), (0.0, chunk), y - base,
                        method='LSODA', rtol=1e-10, atol=atol, events=(weaker, flat),
                        jac=lambda _, x: _velocity_jacobian(system, base + x, s),
                        dense_output=True)
        near = _closest_to_a_change_point(system, base, sol, s, y)
        y = base + sol.y[:, -1]
        elapsed += float(sol.t[-1])
        if near is not None:
            passed = _through_change_point(system, near, s, push_offs)
            if passed is not None:
                return passed
        if sol.status < 0 and sol.t[-1] == 0.0:
            # the integrator cannot leave y: a flow kept mirror-symmetric to the last bit
            # reached a module's opened crossing (Nehalem kernel, bench_round_commands seed
            # 1 stream 1 at s = 0.6006: 200 legs stalled at t = 0); its branches decide
            passed = _through_change_point(system, y, s, push_offs, opened=True)
            if passed is not None:
                return passed
            raise NoRest(f'the flow stalls at s={s!r} on {y} (no way out found)')
        if sol.status != 1:
            chunk *= 4.0
    raise NoRest(f'no certified rest at s={s!r} from {y0} within {MAX_LEGS} legs')


def _velocity(system, y, s):
    spend('the flow', s)
    return system.velocity(y, s)


def _velocity_jacobian(system, y, s):
    spend("the flow's Jacobian", s)
    return system.velocity_jacobian(y, s)


def _flat_level(system, y, s):
    """The flatness (``singular_chord``) at which a leg from y stops to look for a change
    point: CHANGE_POINT_GRADIENT, or a tenth of y's own if y is already that flat.  A leg
    that ended on this event where no crossing was found (a module flat at a linkage
    limit: its chord's solution set does not cross itself) starts on the event's root;
    with the same level the integrator finds the event again at t = 0, and every leg
    after it stops there (the flat-module linkage test: 200 empty legs at s = 0.5039)."""
    return min(CHANGE_POINT_GRADIENT, 0.1 * system.singular_chord(y, s))


def _closest_to_a_change_point(system, base, sol, s, start):
    """The leg's state closest to a module's flat change point, if the leg came within
    CHANGE_POINT_GRADIENT of one (by its event, or stepping over it: both of a module's
    rods turned through its base line, sampled on the dense output), else None."""
    end = base + sol.y[:, -1]
    if sol.status == 1 and sol.t_events[1].size:
        return end
    start_sides = np.sign(np.sin(start))
    turned = np.all((start_sides * np.sign(np.sin(end))).reshape(-1, 2) < 0, axis=1)
    # (the top module has no chord above it, so no change point: its rods turning through
    # its base line is no sign of one; taken for one, the leg's start was returned, next to
    # the crossing just left, and the flow went back to it without end)
    if not np.any(turned[:-1]):
        return None
    samples = [base + sol.sol(t) for t in np.linspace(0.0, float(sol.t[-1]), 201)]
    flatness = [system.singular_chord(x, s) for x in samples]
    k = int(np.argmin(flatness))
    return samples[k] if flatness[k] <= CHANGE_POINT_GRADIENT else None


def _through_change_point(system, y, s, push_offs, opened=False):
    """The flow reached a module's change point: it goes on along the half-branch of
    steepest descent (:func:`descent_rate`) among those on which the mechanism moves away
    from the crossing (the velocity there points out); the other half-branches' landings
    are kept as ``alternatives`` (and the rest marked ``ambiguous``).  None if y is not at
    a crossing (a sharply curving branch next to one: flow on).

    Why steepest descent and not the lowest landing: the released mechanism does not
    choose by the energy of where a way leads.  A stiff-spring node model, where nothing
    degenerates at a change point (test/node_spring_flow.py), flows through module 0's
    change point onto the steepest half-branch, node drag and pivot damping alike
    (test/test_perfect_chord_ramp_landing.py); the lower-landing rule took the other one.
    Checked on two change points: the nearly symmetric N = 3 head-load fold
    (test_reference_tracking.py::test_n3_nearly_symmetric_neck_head_load_folds_where_the_
    tracker_says) and the perfect N = 3 chord ramp (its branch point, PERFECT_NECKS)."""
    found = system.change_point_branches(y, s, opened=opened)
    if found is None:
        return None
    crossing, states = found
    leaving = [x for x in states if float(system.velocity(x, s) @ (x - crossing)) > 0]
    if not leaving:
        raise NoRest(f'the flow rests on a change point at s={s!r} (not certified)')
    rates = [descent_rate(system, crossing, x, s) for x in leaving]
    landings = [flow_to_rest(system, x, s, push_offs) for x in leaving]
    best = landings[int(np.argmax(rates))]
    others = [r.state for r in landings if angle_distance(r.state, best.state) > 1e-6]
    return Rest(best.state, bool(others) or any(r.ambiguous for r in landings), others)


def descent_rate(system, crossing, x, s):
    """The energy drop per unit length from the crossing to x, a state a short way out
    along one half-branch: (U(crossing) - U(x)) / |x - crossing|, the length in the
    angles (the metric of this reference's gradient flow).  The flow released at the
    crossing leaves along the half-branch where this is largest."""
    length = float(np.linalg.norm(np.asarray(x) - np.asarray(crossing)))
    return (system.energy(crossing, s) - system.energy(x, s)) / length


def _push_off(system, star, mode, s, push_offs):
    landings = [flow_to_rest(system, star + sign * PUSH_OFF * mode / np.max(np.abs(mode)), s,
                             push_offs - 1, anchor=star) for sign in (1.0, -1.0)]
    a, b = landings
    ambiguous = angle_distance(a.state, b.state) > 1e-6
    energies = [system.energy(r.state, s) for r in landings]
    best = landings[int(np.argmin(energies))]
    # the other way is an alternative only where it is as low (mirror images of a
    # symmetric saddle: which one a perfect mechanism takes is a convention)
    same = 1e-12 * system.rate(s)
    others = [r.state for r, e in zip(landings, energies)
              if ambiguous and r is not best and e <= min(energies) + same]
    return Rest(best.state, ambiguous or a.ambiguous or b.ambiguous, others)


def settle_reference(system, theta, s=0.0) -> Rest:
    return flow_to_rest(system, system.start_state(theta), s)


@dataclass
class ReferenceJump:
    """A jump of the quasi-static path: the mechanism rests continuously up to ``s_before``
    and lands elsewhere at ``s_after`` (``s_after - s_before <= JUMP_BRACKET``)."""

    s: float                  # critical point (solved), or the bracket's middle
    s_before: float
    s_after: float
    departure: np.ndarray     # last continuous state (at s_before)
    landing: np.ndarray       # rest point at s_after
    kind: str                 # 'fold' (the critical mode meets dG/ds) or 'branch_point'
    solved: bool              # s comes from the critical-point solve
    ambiguous: bool = False
    alternatives: list = field(default_factory=list)    # other landings (see Rest)


@dataclass
class ReferencePassage:
    """A supercritical branch point passed continuously: the minimum buckles onto one of
    two new minima that grow out of it like sqrt(s - s*) (not a jump)."""

    s: float                  # critical point (solved), or the bracket's middle
    departure: np.ndarray     # last state on the old branch (just before s)
    onward: np.ndarray        # rest point on the buckled branch at ``s_onward``
    s_onward: float
    #: The other side's rest point (a perfect pitchfork: equal energies, the side is a
    #: convention; see ``other_sides``).
    alternatives: list = field(default_factory=list)


@dataclass
class ReferencePath:
    final: np.ndarray
    jumps: list = field(default_factory=list)
    steps: int = 0
    start: np.ndarray = None
    passages: list = field(default_factory=list)


def quasi_static_path(system, theta, s0=0.0, s1=1.0,
                      max_motion=MAX_STEP_MOTION) -> ReferencePath:
    """Follow the overdamped mechanism from rest near ``theta`` at s0 to s1 (within the
    work budget: :func:`work_budget`).  ``max_motion``: a step that moves the mechanism
    farther (rad) is split; a snap smaller than it can pass for the branch's own motion
    where the branch moves fast (a fold's square root), so paths with small snaps (a
    module under 1e-5 .. 1e-4 k L next to rho = L: 0.8 deg) need a finer one."""
    with work_budget():
        return _quasi_static_path(system, theta, s0, s1, max_motion)


def _quasi_static_path(system, theta, s0, s1, max_motion=MAX_STEP_MOTION):
    y = settle_reference(system, theta, s0).state
    path = ReferencePath(final=y, start=y.copy())
    s, ds, slope = s0, FIRST_STEP, None
    while s < s1:
        s_new = min(s1, s + ds)
        path.steps += 1
        if path.steps > MAX_STEPS:
            raise NoRest(f'the reference gave up after {MAX_STEPS} steps, at s={s!r}')
        try:
            rest = flow_to_rest(system, y, s_new, push_offs=0, close=True)
        except Stalled:                 # the branch has become a saddle: a jump
            rest = None
        if rest is None:
            jump = _bisect_jump(system, s, y, s_new, None, stalled=True)
            if isinstance(jump, ReferencePassage):
                path.passages.append(jump)
                s, y, slope, ds = jump.s_onward, jump.onward, None, MIN_STEP
                continue
            if not isinstance(jump, ReferenceJump):
                raise NoRest(f'the branch became a saddle near s={s_new!r} but no jump found')
            path.jumps.append(jump)
            s, y, slope, ds = jump.s_after, jump.landing, None, FIRST_STEP
            continue
        motion = angle_distance(rest.state, y)
        # (with no slope yet, as right after a bisection found the branch going on, a
        # step of MIN_STEP that moves more than CLOSE_DISTANCE is looked at too: seed 0
        # stream 6's module 0 reached its flat crossing at s = 1 and the last step, 1.9e-9
        # long, took the 0.015 rad snap off it for the branch's own motion)
        suspicious = motion > max_motion or (
            slope is not None and motion > 3.0 * slope * (s_new - s) + 1e-6) or (
            slope is None and s_new - s <= MIN_STEP and motion > CLOSE_DISTANCE)
        if suspicious and s_new - s > MIN_STEP:
            ds = 0.25 * (s_new - s)
            continue
        if suspicious:
            jump = _bisect_jump(system, s, y, s_new, rest)
            if isinstance(jump, ReferencePassage):
                path.passages.append(jump)
                s, y, slope, ds = jump.s_onward, jump.onward, None, MIN_STEP
                continue
            if isinstance(jump, ReferenceJump):
                path.jumps.append(jump)
                s, y, slope, ds = jump.s_after, jump.landing, None, FIRST_STEP
                continue
            # no jump: the branch continues to the bracket's end; step on from there
            s, y, slope, ds = jump[0], jump[1], None, MIN_STEP
            continue
        slope = None if suspicious else motion / (s_new - s)
        s, y = s_new, rest.state
        ds = min(MAX_STEP, 2.0 * ds) if motion < 0.25 * max_motion else ds
    snap = _snap_off_crossing(system, y, s1)
    if snap is not None:
        path.jumps.append(snap)
        y = snap.landing
    path.final = y
    return path


def _snap_off_crossing(system, y, s):
    """The jump off a module's flat crossing the path ends on at s (a command ending where
    rho(i) + rho(i+1) = L1 + L2 to rounding), or None.

    Where the end state lies within the chords' rounding radius of the crossing, the
    model does not tell it from the crossing (Newton 'converges' anywhere there), so the
    crossing's half-branches decide, as for a flow that reaches one (:func:`_through_
    change_point`): where the mechanism released there leaves downhill and comes to
    rest more than JUMP_DISTANCE away, it jumps there, at fixed s, releasing energy.
    Seed 0 stream 6 of bench_round_commands at s = 1: module 0 2e-8 rad from its
    crossing (radius 3e-8), two half-branches leave downhill, and the mechanism snaps
    0.015 rad (4e-4 J).  Only at the path's end: elsewhere a step's flow meets the
    crossing itself."""
    found = system.change_point_branches(y, s)
    if found is None:
        return None
    crossing, states = found
    if angle_distance(crossing, y) > max(system.chord_rounding_radius(y, s), 1e-8):
        return None
    passed = _through_change_point(system, crossing, s, push_offs=2)
    if (passed is None or angle_distance(passed.state, y) <= JUMP_DISTANCE
            or system.energy(passed.state, s) >= system.energy(crossing, s)):
        return None
    return ReferenceJump(s=s, s_before=s, s_after=s, departure=y, landing=passed.state,
                         kind='fold', solved=False, ambiguous=passed.ambiguous,
                         alternatives=passed.alternatives)


def _bisect_jump(system, s_a, y_a, s_b, rest_b, stalled=False):
    """Bisect [s_a, s_b] on whether the branch's minimum still continues next to the last
    rest (see ``_nearby_minimum``); then the overdamped flow from the last rest with the
    parameters at the bracket's end decides: a jump only if it lands far away.
    A branch point whose landing closes in on the departure like sqrt(s - s*) as the
    freeze moves towards s* is passed continuously (:func:`_passage`).
    Returns the :class:`ReferenceJump`, a :class:`ReferencePassage`, or (s, state) where
    the branch continues."""
    y_b = None if rest_b is None else rest_b.state
    while s_b - s_a > JUMP_BRACKET * max(1.0, abs(s_a)):
        s_m = 0.5 * (s_a + s_b)
        near = _nearby_minimum(system, y_a, s_m, y_b)
        if near is not None:
            s_a, y_a = s_m, near
        else:           # no minimum continues the branch here: the flow leaves (checked
            s_b = s_m   # below at the bracket's end, where the landing is computed)
    if stalled:
        # the branch's minimum became a saddle: passed continuously if a buckled minimum
        # grows out of it (checked off the branch point: right at it the escape from the
        # saddle is a flow of time ~ 1 / lambda_min, hours of integration)
        passage = _passage(system, y_a, s_a, s_b)
        if passage is not None:
            return passage
    s_land = s_b
    if _nearby_minimum(system, y_a, s_b, None) is None:
        # past a fold: the flow from y_a crosses the fold's ghost, a passage of time
        # ~ 1 / sqrt(s - s*) (~1e9 relaxation times at 1e-9 past: minutes for an N = 3
        # neck), so the landing is taken LANDING_OFFSET on (it moves continuously with s)
        s_land = min(1.0, s_b + LANDING_OFFSET)
    try:
        rest_b = flow_to_rest(system, y_a, s_land, push_offs=0)
    except Stalled:
        # a saddle: escaping it right at the event is a flow of time ~ 1 / lambda; the
        # landing is taken a little further on, where lambda is not tiny
        s_land = min(1.0, s_b + LANDING_OFFSET) if s_b >= s_a else s_b
        rest_b = flow_to_rest(system, y_a, s_land)
    if angle_distance(rest_b.state, y_a) <= JUMP_DISTANCE and stalled:
        # the step stalled on a saddle (a branch point) but the bisection ended within
        # rounding of it: the landing is taken a little further on
        rest_b = flow_to_rest(system, y_a, min(1.0, s_b + LANDING_OFFSET))
    if _continuous(system, y_a, s_land, rest_b.state):
        return s_land, rest_b.state       # continuous after all: where to step on from
    passage = None if stalled else _passage(system, y_a, s_a, s_b)
    if passage is not None:
        return passage
    s_star, solved = critical_point_in(system, y_a, s_a, s_b)
    kind = classify(system, y_a, s_a)
    return ReferenceJump(s=s_star, s_before=s_a, s_after=s_b, departure=y_a,
                         landing=rest_b.state, kind=kind, solved=solved,
                         ambiguous=rest_b.ambiguous, alternatives=rest_b.alternatives)


def _passage(system, y_a, s_a, s_b):
    """The :class:`ReferencePassage` if the critical point bracketed by [s_a, s_b] is a
    branch point passed continuously (a supercritical pitchfork, no jump), else None.
    Frozen at s* + LANDING_OFFSET, the flow from the departure y_a rests on a buckled
    minimum; frozen PASSAGE_SHRINK times closer to s*, it rests sqrt(PASSAGE_SHRINK)
    times closer to y_a: the normal form's sqrt(s - s*).  A subcritical pitchfork's
    landing (and a fold's) stays a finite distance away however close the freeze.
    Only tried where the soft mode is nearly orthogonal to dG/ds (two flows each)."""
    if mode_alignment(system, y_a, s_a) > PASSAGE_ALIGNMENT:
        return None
    s_star = critical_point_in(system, y_a, s_a, s_b)[0]
    s_far = min(1.0, s_star + LANDING_OFFSET)
    if not s_far > s_star:
        return None
    try:
        rest = flow_to_rest(system, y_a, s_far)
        near = flow_to_rest(system, y_a, s_star + (s_far - s_star) / PASSAGE_SHRINK).state
    except (NoRest, Stalled):
        return None
    far = rest.state
    expected = angle_distance(far, y_a) / math.sqrt(PASSAGE_SHRINK)
    if not (angle_distance(far, y_a) > JUMP_DISTANCE
            and expected / PASSAGE_SLACK <= angle_distance(near, y_a) <= expected * PASSAGE_SLACK):
        return None
    return ReferencePassage(s=s_star, departure=y_a, onward=far, s_onward=s_far,
                            alternatives=rest.alternatives)


def other_sides(system, path):
    """The reference paths that took the other side of a perfect pitchfork passed
    continuously (equal energies: which side is a convention): for each passage with an
    alternative, the path up to it followed on from the other side (each within a work
    budget of its own)."""
    for passage in path.passages:
        for other in passage.alternatives:
            onward = quasi_static_path(system, other, passage.s_onward)
            yield ReferencePath(
                final=onward.final, start=path.start, steps=path.steps + onward.steps,
                jumps=[j for j in path.jumps if j.s < passage.s] + onward.jumps,
                passages=[p for p in path.passages if p.s <= passage.s] + onward.passages)


def _continuous(system, y_a, s_b, landing):
    """Whether the rest at s_b is the branch of y_a going on: within JUMP_DISTANCE, or
    Newton from y_a continues to it, or it is the fold itself: close, with lambda_min ~ 0
    (a bracket's end within ~1e-10 of a fold, where the gradient of the fold's ghost is
    below the Newton tolerance; the next step finds the jump)."""
    if angle_distance(landing, y_a) <= JUMP_DISTANCE or _continues(system, y_a, s_b, landing):
        return True
    values, _ = system.stability(landing, s_b)
    return (angle_distance(landing, y_a) <= CLOSE_DISTANCE
            and values[0] <= 1e-6 * abs(values[-1]))


def _continues(system, y_a, s_b, landing):
    """Whether ``landing`` is the minimum y_a continues to at s_b: Newton from y_a ends on
    a stable point that is the landing (modulo 2 pi).  Next to a fold the branch moves
    like sqrt(s* - s), ~1e-5 rad over a bisection bracket, more than any fixed
    "same state" distance that still tells a small jump from no jump.  But only that far
    (CLOSE_DISTANCE): Newton's own steps are not a path of rest points, and where the
    branch ends next to a module's flat crossing Newton from y_a went 0.0475 rad in one
    solve to the minimum the mechanism jumps to (seed 0 stream 7, see energy_seen_from)."""
    star, ok = system.critical_point(y_a, s_b)
    return bool(ok and system.stability(star, s_b)[0][0] > 0
                and angle_distance(star, landing) <= 1e-9
                and angle_distance(star, y_a) <= CLOSE_DISTANCE)


def _nearby_minimum(system, y_a, s_m, y_b):
    """Inside a jump's bracket, the branch's minimum at s_m next to y_a, if Newton finds
    one closer to y_a than the landing, lower in energy than y_a: by the fold's normal
    form the previous minimum y_a lies on the far side of it from the saddle that the
    fold merges it with, inside its basin, so the flow from y_a ends there (the flow
    itself is slow here: lambda_min -> 0)."""
    star, ok = system.critical_point(y_a, s_m)
    if not ok or system.stability(star, s_m)[0][0] <= 0:
        return None
    if y_b is not None and angle_distance(star, y_a) >= angle_distance(star, y_b):
        return None
    slack = 1e-13 * system.rate(s_m)     # energies differ by ~lambda d^2 ~ rounding here
    return star if system.energy(star, s_m) <= system.energy_seen_from(star, y_a, s_m) + slack \
        else None


def critical_solve(system, y, s):
    """{grad U = 0, det H = 0} solved from (y, s): scipy's root result, x = (state, [chord
    multipliers,] s)."""
    scale = None
    if isinstance(system, NeckSystem):
        mu = system.multipliers(y, s)
        z0 = np.concatenate([y, mu, [s]])
        # a flat module's chord multiplier is ~1e5..1e7 N against angles of ~1: hybr's own
        # column scaling does not always bridge that
        scale = np.concatenate([np.ones(len(y)), 1.0 / np.maximum(np.abs(mu), 1.0), [1.0]])
    else:
        z0 = np.concatenate([y, [s]])
    tries = [('hybr', {})] + ([('hybr', {'diag': scale})] if scale is not None else []) \
        + [('lm', {})]
    solutions = []
    with np.errstate(all='ignore'):
        for method, options in tries:
            sol = root(system.critical_residual, z0, method=method,
                       options={'xtol': 1e-14, **options})
            if sol.success and _residual(system, sol) <= CRITICAL_SOLVED:
                return sol
            solutions.append(sol)
    # The first try that meets the equations; else the smallest residual of all (each may
    # stop by its own test short of the equations' rounding floor, or go astray).  Plain
    # hybr stopped 'converged' (its steps below xtol) at 3.7e-7, 2e-5 in s off the fold,
    # from a start 5e-13 in s from one where it met them to 8e-16 (test_neck_fold_next_to_
    # a_flat_module_...).  2.3e-6 in s before
    # test_neck_fold_next_to_a_flat_module_...'s fold, hybr stopped at 2.8e-3 on the
    # Nehalem kernel with numpy's SSE loops (lm: 7e-16) and at 0.2 on the Sandybridge
    # kernel, where lm went astray too and the scaled hybr met the fold's equations to
    # 5e-16; at test_a_neck_command_from_a_state_left_at_a_fold_...'s fold on Nehalem the
    # scaled hybr stopped 'converged' at 4.7e-10, where lm reaches the floor
    return min(solutions, key=lambda r: _residual(system, r))


#: A fold solve whose equations are met to this is taken (their rounding floor is ~1e-15
#: for a module and up to ~1e-11 next to a flat module's chord force, ~6e5 N).
CRITICAL_SOLVED = 1e-10


def _residual(system, solution):
    """How far ``solution`` misses the fold's equations: the largest equilibrium residual,
    and the determinant's excess over its own rounding floor.  Next to a flat module
    (chord force 6.5e7 N) the scaled determinant moves by up to 2.7e-5 when the state
    moves by 2e-16 of itself: its value there (7.9e-7 at the fold, 8e-16 from a start
    5e-13 in s away) is rounding, and choosing by it picked a solve 2e-5 in s off the
    fold (test_neck_fold_next_to_a_flat_module_...)."""
    x = solution.x
    f = system.critical_residual(x)
    rng = np.random.default_rng(0)
    floor = max(abs(system.critical_residual(x * (1.0 + 2e-16 * rng.standard_normal(len(x))))[-1]
                    - f[-1]) for _ in range(8))
    return float(max(np.max(np.abs(f[:-1]), initial=0.0), abs(f[-1]) - floor))


def critical_point_in(system, y_a, s_a, s_b, slack=1e-10):
    """Solve {grad U = 0, det H = 0} from the bracket; (s, solved) if it lands in it."""
    sol = critical_solve(system, y_a, s_a)
    s = float(sol.x[-1])
    if sol.success and s_a - slack <= s <= s_b + slack:
        return s, True
    return 0.5 * (s_a + s_b), False


def classify(system, y, s, h=1e-6):
    """'branch_point' if the critical mode is orthogonal to dG/ds, else 'fold'."""
    return 'branch_point' if mode_alignment(system, y, s, h) < 1e-6 else 'fold'


def mode_alignment(system, y, s, h=1e-6):
    """|psi . dG/ds| / (|psi| |dG/ds|), psi the softest mode: ~1 at a fold, 0 at a
    branch point (0 too if the parameters do not move the equilibrium conditions)."""
    _, modes = system.stability(y, s)
    psi = modes[:, 0]
    if isinstance(system, NeckSystem):
        mu = system.multipliers(y, s)
        g_s = (system.lagrangian_gradient(y, mu, s + h)
               - system.lagrangian_gradient(y, mu, s - h)) / (2 * h)
    else:
        g_s = (system.gradient(y, s + h) - system.gradient(y, s - h)) / (2 * h)
    norm = float(np.linalg.norm(g_s))
    if norm == 0.0:
        return 0.0
    return abs(float(psi @ g_s)) / (norm * float(np.linalg.norm(psi)))


def all_module_equilibria(params):
    """Every equilibrium of one module by the multi-start oracle: [(theta, stable)]."""
    result = oracle_equilibria(params)
    return [(np.array(q), st) for q, st in zip(result.points, result.stable)]
