"""Snap-through dynamics of one module (DESIGN.md section 9).

The quasi-static tracker says where the mechanism lands after a jump; this says
what happens on the way.  Each rod is a uniform slender bar of mass ``m_i``
pivoting at its base point (A1 for rod 1, A2 for rod 2), with moment of inertia
``I_i = m_i L_i^2 / 3`` and a viscous damping ``c`` (N m s/rad) at each pivot.
The actuator is kinematic: rho(t) is prescribed (:class:`RhoRamp`).  The motion
obeys::

    I_i theta_i'' = -dU/dtheta_i - c theta_i'

with U the module's potential (springs, loads, and the rod weights, which
:mod:`.module` already places as exact nodal forces).  Rod 2's pivot A2 moves
with rho, which adds ``-(m2 L2 / 2) rho'' sin(theta2)`` to rod 2's equation;
rho'' is zero on the ramp and the hold, and the impulses at the two kinks of a
constant-rate profile are neglected (a real actuator rounds its velocity
steps).  Integration is scipy's ``solve_ivp`` (DOP853, tight tolerances, dense
output); nothing here is a hand-written integrator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp
from scipy.optimize import brentq, minimize_scalar

from . import module as _m
from .module import InvalidParameterError, ModuleParams
from .tracking import ModulePath, ModuleTrack, settle, track_module

#: |theta'| (rad/s) of either rod that marks the onset of a snap.
ONSET_SPEED = 1.0
#: Settled: |theta - final| below this (rad) and |theta'| below this (rad/s), for good.
SETTLE_TOLERANCE = 1e-6
#: Longest hold (s) when the hold is "until settled".
MAX_HOLD = 60.0
#: Landings closer than this (rad, per angle) are the same equilibrium.
SAME_LANDING = 1e-4


@dataclass(frozen=True)
class RhoRamp:
    """rho(t): from ``rho0`` to ``rho1`` at constant ``rate`` (m/s, > 0), then held."""

    rho0: float
    rho1: float
    rate: float

    def __post_init__(self):
        for name in ('rho0', 'rho1', 'rate'):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InvalidParameterError(f'{name} must be a finite number, got {value!r}')
        if not self.rate > 0.0:
            raise InvalidParameterError(f'rate must be positive, got {self.rate!r}')

    @property
    def duration(self):
        """Time (s) the ramp takes."""
        return abs(self.rho1 - self.rho0) / self.rate

    def fraction(self, t):
        """Path parameter s in [0, 1] at time t (1 during the hold)."""
        duration = self.duration
        return 1.0 if duration == 0.0 or t >= duration else max(t, 0.0) / duration

    def rho(self, t):
        """rho (m) at time(s) t."""
        t = np.asarray(t, dtype=float)
        duration = self.duration
        if duration == 0.0:
            return np.full_like(t, self.rho1)
        return self.rho0 + np.clip(t / duration, 0.0, 1.0) * (self.rho1 - self.rho0)


@dataclass(frozen=True)
class SnapHistory:
    """Time history of a simulation: ``t`` (s), ``rho`` (m), ``theta`` and
    ``theta_dot`` (shape (n, 2), rad and rad/s), ``actuator_force`` (N, along +x
    on A2, including rod 2's dynamic reaction)."""

    t: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    actuator_force: np.ndarray


@dataclass(frozen=True)
class Snap:
    """Result of :func:`simulate_snap`: the history, the summary and the quasi-static
    prediction beside it.  ``static_fold_rho`` is the tracker's first jump (or None).

    ``summary`` keys: ``onset_rho`` (rho when either |theta'| first exceeds
    ONSET_SPEED, or None), ``onset_time``, ``peak_speed`` (rad/s), ``peak_actuator_force``
    (N, signed, largest magnitude), ``overshoot`` (rad past the final angle after the
    onset), ``settle_time`` (s from the onset, or from the ramp's end if nothing snapped,
    until within SETTLE_TOLERANCE for good; None if not settled), ``settled``, ``final``
    ({theta1, theta2, speed} at the end), ``quasi_static`` (the tracker's jumps and final
    state) and ``lands_elsewhere`` (the rest state is not the tracker's).
    """

    history: SnapHistory
    summary: dict
    quasi_static: ModuleTrack
    static_fold_rho: float | None
    solution: OdeSolution = field(repr=False)


class _Module:
    """The equations of motion of one module along a rho ramp."""

    def __init__(self, params: ModuleParams, ramp: RhoRamp, damping: float):
        if params.m1 <= 0.0 or params.m2 <= 0.0:
            raise InvalidParameterError(
                f'dynamics needs positive rod masses, got m1={params.m1!r}, m2={params.m2!r}')
        if not math.isfinite(damping) or damping < 0.0:
            raise InvalidParameterError(f'damping must be finite and >= 0, got {damping!r}')
        self.start = params.with_(rho=ramp.rho0)
        self.end = params.with_(rho=ramp.rho1)
        self.path = ModulePath(self.start, self.end)
        self.ramp = ramp
        self.damping = float(damping)
        self.inertia = np.array([params.m1 * params.L1 ** 2, params.m2 * params.L2 ** 2]) / 3.0

    def rhs(self, t, y):
        """(theta', theta'') at time t."""
        grad = self.path.residual(y[:2], self.ramp.fraction(t))
        acc = (-grad - self.damping * y[2:]) / self.inertia
        return np.array([y[2], y[3], acc[0], acc[1]])

    def gradient(self, t, theta):
        """dU/dtheta at samples (t, theta): vectorised on the hold, per sample on the ramp."""
        theta = np.atleast_2d(theta)
        out = _m.gradient(self.end, theta)
        for i in np.flatnonzero(np.asarray(t) < self.ramp.duration):
            out[i] = self.path.residual(theta[i], self.ramp.fraction(t[i]))
        return out

    def acceleration(self, t, y):
        """theta'' at samples; ``y`` has shape (n, 4)."""
        return (-self.gradient(t, y[:, :2]) - self.damping * y[:, 2:]) / self.inertia

    def actuator_force(self, t, y):
        """Force (N) the actuator exerts on A2 along +x, at samples ``y`` (shape (n, 4)).

        The slider A2 is massless; the forces on it along x are the actuator's P,
        spring a's ``ka (x3 - rho)`` and minus rod 2's pivot reaction R.  Newton for
        rod 2 along x: ``m2 x_G'' = R_x + F4_x`` with F4 the spring and load forces
        at A4 (gravity has no x part).  Hence ``P = ka (rho - x3) - F4_x + m2 x_G''``
        and ``ka (rho - x3) - F4_x`` is exactly dU/drho (the static force), so::

            P = dU/drho + m2 x_G'',   x_G = rho - (L2 / 2) cos theta2,
            x_G'' = (L2 / 2) (sin theta2 theta2'' + cos theta2 theta2'^2)   (rho'' = 0).

        Rod 1's pivot A1 is fixed: its reaction goes to the frame, not the actuator.
        """
        t = np.asarray(t, dtype=float)
        theta, omega = y[:, :2], y[:, 2:]
        rho = self.ramp.rho(t)
        static = _m.actuator_force(self.end, theta) + (rho - self.end.rho) * (
            self.end.ka + self.end.kb + self.end.kc)      # dU/drho is linear in rho
        alpha2 = self.acceleration(t, y)[:, 1]
        t2 = theta[:, 1]
        x_g_ddot = 0.5 * self.end.L2 * (np.sin(t2) * alpha2 + np.cos(t2) * omega[:, 1] ** 2)
        return static + self.end.m2 * x_g_ddot

    def mechanical_energy_near(self, y, theta_eq):
        """Kinetic energy plus the quadratic potential about ``theta_eq`` (at rho1)."""
        delta = _wrap(y[:2] - theta_eq)
        h = _m.hessian(self.end, theta_eq)
        return 0.5 * float(self.inertia @ y[2:] ** 2) + 0.5 * float(delta @ h @ delta)


def _wrap(angle):
    return (np.asarray(angle, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def _onset_events():
    """Event functions: either rod's |theta'| crosses ONSET_SPEED."""
    def rod1(t, y):
        return y[2] * y[2] - ONSET_SPEED ** 2

    def rod2(t, y):
        return y[3] * y[3] - ONSET_SPEED ** 2

    return [rod1, rod2]


@dataclass(frozen=True)
class SolverSettings:
    """solve_ivp settings: tolerances that keep the reported figures to 0.1 %."""

    method: str = 'DOP853'
    rtol: float = 1e-10
    atol: float = 1e-12
    chunk: float = 1.0          # s of hold between checks for "settled for good"


def _integrate(system, y0, t0, t1, settings):
    sol = solve_ivp(system.rhs, (t0, t1), y0, method=settings.method, rtol=settings.rtol,
                    atol=settings.atol, dense_output=True, events=_onset_events())
    if sol.status < 0:
        raise RuntimeError(f'the ODE solver failed: {sol.message}')
    return sol


def _settled_for_good(system, y):
    """The stable equilibrium the state is trapped at within SETTLE_TOLERANCE, or None.

    With damping the mechanical energy never grows while rho is held, so once it is
    below the least energy any state outside the tolerance box has (half the
    smallest of the Hessian's eigenvalues and the inertias, times tol^2), the
    motion stays in the box for good.
    """
    if system.damping == 0.0 or np.max(np.abs(y[2:])) > 1e-3:
        return None
    try:
        eq = settle(system.end, y[:2])
    except (RuntimeError, ValueError):
        return None
    theta_eq = eq.theta + 2.0 * math.pi * np.round((y[:2] - eq.theta) / (2.0 * math.pi))
    floor = 0.5 * min(float(np.min(eq.eigenvalues)), float(np.min(system.inertia)))
    if system.mechanical_energy_near(y, theta_eq) < 0.5 * floor * SETTLE_TOLERANCE ** 2:
        return theta_eq
    return None


def _run(system, y0, hold, settings):
    """Integrate the ramp, then the hold; returns (OdeSolution, event times, settled eq)."""
    ramp_end = system.ramp.duration
    pieces = []
    if ramp_end > 0.0:
        pieces.append(_integrate(system, y0, 0.0, ramp_end, settings))
        y0 = pieces[-1].y[:, -1]
    limit = MAX_HOLD if hold is None else hold
    t, settled = ramp_end, None
    while t < ramp_end + limit:
        t_next = min(t + settings.chunk, ramp_end + limit)
        pieces.append(_integrate(system, y0, t, t_next, settings))
        t, y0 = t_next, pieces[-1].y[:, -1]
        settled = _settled_for_good(system, y0)
        if settled is not None and hold is None:
            break
    ts = np.concatenate([pieces[0].t] + [p.t[1:] for p in pieces[1:]])
    interpolants = [f for p in pieces for f in p.sol.interpolants]
    events = [float(e) for p in pieces for ev in p.t_events for e in ev]
    return OdeSolution(ts, interpolants), events, settled


def _sample_times(solution, per_step=4):
    """The solver's step points, each step split into ``per_step`` parts."""
    ts = solution.ts
    fractions = np.arange(per_step) / per_step
    inner = (ts[:-1, None] + np.diff(ts)[:, None] * fractions).ravel()
    return np.append(inner, ts[-1])


def _refined_peak(f, ts, values):
    """Largest f on the samples, refined on the dense output around the best sample."""
    i = int(np.argmax(values))
    lo, hi = ts[max(i - 1, 0)], ts[min(i + 1, len(ts) - 1)]
    best = float(values[i])
    if hi > lo:
        res = minimize_scalar(lambda t: -f(t), bounds=(lo, hi), method='bounded',
                              options={'xatol': 1e-12 * max(1.0, hi)})
        best = max(best, float(f(res.x)))
    return best


def _last_exit(box, ts, values):
    """Time after which ``box`` (<= 0 inside) stays <= 0: the last crossing, refined."""
    outside = np.flatnonzero(values > 0.0)
    if outside.size == 0:
        return float(ts[0])
    i = int(outside[-1])
    if i == len(ts) - 1:
        return None
    return float(brentq(box, ts[i], ts[i + 1], xtol=1e-12))


def _history(system, solution, ts):
    y = solution(ts).T
    return SnapHistory(t=ts, rho=system.ramp.rho(ts), theta=y[:, :2].copy(),
                       theta_dot=y[:, 2:].copy(), actuator_force=system.actuator_force(ts, y))


def _summary(system, solution, history, events, settled, track):
    """The figures of the issue, from the history refined on the dense output."""
    ts = history.t
    onset = min(events) if events else None

    def speed(t):
        return float(np.max(np.abs(solution(t)[2:])))

    def force(t):
        return float(system.actuator_force(np.array([t]), solution(t)[None, :])[0])

    peak_speed = _refined_peak(speed, ts, np.max(np.abs(history.theta_dot), axis=1))
    sign = 1.0 if np.max(history.actuator_force) >= -np.min(history.actuator_force) else -1.0
    peak_force = sign * _refined_peak(lambda t: sign * force(t), ts, sign * history.actuator_force)
    y_end = solution(ts[-1])
    final_theta = settled if settled is not None else y_end[:2]
    from_t = onset if onset is not None else 0.0
    overshoot = _overshoot(solution, ts, history, final_theta, from_t)
    settle_time = None
    if settled is not None:
        def box(t):
            y = solution(t)
            return max(float(np.max(np.abs(y[:2] - settled))),
                       float(np.max(np.abs(y[2:])))) / SETTLE_TOLERANCE - 1.0
        dev = np.maximum(np.max(np.abs(history.theta - settled), axis=1),
                         np.max(np.abs(history.theta_dot), axis=1)) / SETTLE_TOLERANCE - 1.0
        exit_time = _last_exit(box, ts, dev)
        start = onset if onset is not None else system.ramp.duration
        settle_time = None if exit_time is None else max(exit_time - start, 0.0)
    return {
        'onset_rho': None if onset is None else float(system.ramp.rho(onset)),
        'onset_time': onset,
        'peak_speed': peak_speed,
        'peak_actuator_force': peak_force,
        'overshoot': overshoot,
        'settle_time': settle_time,
        'settled': settled is not None,
        'final': {'theta1': float(_wrap(y_end[0])), 'theta2': float(_wrap(y_end[1])),
                  'speed': float(np.max(np.abs(y_end[2:])))},
        **_beside_quasi_static(system, track, final_theta),
    }


def _overshoot(solution, ts, history, final_theta, from_t):
    """Largest excursion (rad) of either rod past its final angle, away from where it came.

    Each rod approaches its final angle from the side it was on at ``from_t``
    (the onset, or the start); the overshoot is how far it swings beyond.
    """
    keep = ts >= from_t
    if not np.any(keep):
        return 0.0
    y0 = solution(from_t)[:2]
    direction = np.sign(final_theta - y0)
    beyond = (history.theta[keep] - final_theta) * direction
    worst = np.max(beyond, axis=0)
    rod = int(np.argmax(worst))
    if worst[rod] <= 0.0:
        return 0.0

    def past(t):
        return float((solution(t)[rod] - final_theta[rod]) * direction[rod])

    return max(_refined_peak(past, ts[keep], beyond[:, rod]), 0.0)


def _beside_quasi_static(system, track, final_theta):
    """The tracker's prediction, and whether inertia lands the mechanism elsewhere."""
    jumps = [{'kind': j.kind, 'rho': float(j.params.rho),
              'theta1': float(j.from_theta[0]), 'theta2': float(j.from_theta[1]),
              'landing': {'theta1': float(j.to_theta[0]), 'theta2': float(j.to_theta[1])},
              'actuator_force': float(_m.actuator_force(j.params, j.from_theta))}
             for j in track.jumps]
    predicted = np.array([track.final.theta1, track.final.theta2])
    elsewhere = bool(np.max(np.abs(_wrap(final_theta - predicted))) > SAME_LANDING)
    return {'quasi_static': {'jumps': jumps,
                             'final': {'theta1': float(predicted[0]),
                                       'theta2': float(predicted[1])},
                             'status': track.status},
            'lands_elsewhere': elsewhere}


def simulate_snap(params: ModuleParams, rho_end: float, rate: float, damping: float,
                  theta_guess, hold: float | None = None,
                  settings: SolverSettings = SolverSettings()) -> Snap:
    """Drive rho from ``params.rho`` to ``rho_end`` at ``rate`` (m/s), then hold.

    The module starts at rest in the stable equilibrium whose basin holds
    ``theta_guess``.  ``hold`` is the time (s) held at ``rho_end``; None holds
    until settled for good (at most :data:`MAX_HOLD`).  ``params.m1``, ``m2`` must
    be positive (they set the inertias).  Raises InvalidParameterError on bad input.
    """
    if hold is not None and (not math.isfinite(hold) or hold < 0.0):
        raise InvalidParameterError(f'hold must be finite and >= 0, got {hold!r}')
    ramp = RhoRamp(float(params.rho), float(rho_end), float(rate))
    system = _Module(params, ramp, damping)
    start = settle(system.start, theta_guess)
    solution, events, settled = _run(system, np.array([*start.theta, 0.0, 0.0]), hold, settings)
    history = _history(system, solution, _sample_times(solution))
    track = track_module(system.start, system.end, start.theta)
    summary = _summary(system, solution, history, events, settled, track)
    fold = float(track.jumps[0].params.rho) if track.jumps else None
    return Snap(history=history, summary=summary, quasi_static=track, static_fold_rho=fold,
                solution=solution)


__all__ = ['RhoRamp', 'SnapHistory', 'Snap', 'SolverSettings', 'simulate_snap',
           'ONSET_SPEED', 'SETTLE_TOLERANCE', 'MAX_HOLD']
