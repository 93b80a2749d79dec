"""A transient driven by an actuator ramp: the profile, the integration and its figures.

Shared by the dynamics of one module (:mod:`.dynamics`) and of the neck
(:mod:`.dynamics.neck_snap`): rho(t) runs at constant rate and is then held; scipy's
``solve_ivp`` integrates the ramp and then the hold in chunks until the motion
has settled for good; the figures (onset, peak speed and force, overshoot,
settling time) are read from the dense output, peaks refined by a bounded scalar
search and the settling time by a root bracket on the energy above the rest state.

Angles are read continuously (unwrapped): a rod that swings through pi is not a jump of
2 pi in any figure.  States are compared modulo 2 pi where the mechanism is periodic: the
energy above a rest state (rest detection, the settling time) and landings.

The settling time is the time after which the mechanical energy above the final minimum
stays below the "settled" threshold (the least energy of a state outside the 1e-6 rad,
1e-6 rad/s box about it).  While rho is held and the pivots are damped that energy only
falls, so it is the first time the energy is below the threshold: one crossing of a
falling curve, which moves with the integration error by about that error, and which a
later bump of the computed energy (an integration error: the exact one cannot grow)
cannot move.  The last exit from the box, used before, is decided by whether one swing
of the slowest mode peaks just inside or just outside: half a period for 2e-9 rad.
Precision (fig. 8a's fold and past C1, four OpenBLAS kernels): 3e-5 s at rtol 1e-10 to
1e-13, 1.3e-3 s at 1e-8 (docs/dynamics.md).

A perfectly symmetric mechanism on its symmetric branch past a branch point is an
unstable equilibrium that exact arithmetic never leaves (the equations keep
theta1 = theta2 bit for bit); no real module is that perfect.  Every transient therefore
carries :data:`IMPERFECTION`: a constant torque of IMPERFECTION (ka + kc) L1^2 on rod 1
of the bottom module, in the +theta1 direction -- 1e-13 of the torques its springs
exert (a thousand times the rounding of a sum of them), far below the precision of any
figure (it moves a stable state by ~1e-13 rad), yet enough to leave an unstable one, as
the quasi-static tracker leaves a branch point along its critical mode (whose first
non-zero component it takes positive, as here).  How long the motion lingers on the
unstable branch grows with the logarithm of 1 / IMPERFECTION (as it does with a real
module's imperfections): the onset of such a snap is a model figure, its peak speed and
landing are not (fig. 8a past C1: onset 5.45 s; 5.32 s with 1e-12, 5.69 s with 1e-14;
peak 33.5 rad/s).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp
from scipy.optimize import brentq, minimize_scalar

from ..module.model import InvalidParameterError

#: |theta'| (rad/s) of any rod that marks the onset of a snap.
ONSET_SPEED = 1.0
#: Settled: |theta - final| below this (rad) and |theta'| below this (rad/s), for good.
SETTLE_TOLERANCE = 1e-6
#: Longest hold (s) when the hold is "until settled".
MAX_HOLD = 60.0
#: Rest states closer than this (rad, per angle) are the same equilibrium.
SAME_LANDING = 1e-4
#: Relative size of the built-in imperfection (see the module docstring).
IMPERFECTION = 1e-13
#: Rods slower than this (rad/s) may be at rest: a rest candidate is found from their state.
SLOW = 1e-3
#: Angles closer than this (rad, wrapped) are near the same equilibrium (rest candidates).
NEAR = 1e-3


def imperfection_torque(params):
    """The built-in imperfection (N m) on rod 1 of the module ``params`` (the bottom one)."""
    return IMPERFECTION * (params.ka + params.kc) * params.L1 ** 2


@dataclass(frozen=True)
class Rest:
    """Where a damped transient rests: the rest ``theta`` (rad, continuous with the
    state it was found from), ``excess(t, ys)`` the mechanical energy (J) above that
    minimum of states ``ys`` (shape (n, state size)) at segment times ``t`` while rho is
    held -- a function of the angles modulo 2 pi, as the mechanism is --, and
    ``threshold`` (J): below it the state is trapped within SETTLE_TOLERANCE of ``theta``
    (modulo 2 pi) for good; ``eq`` the verified equilibrium it was found as and
    ``found_at`` the angles of the slow state it was found from."""

    theta: np.ndarray
    excess: object = field(repr=False)
    threshold: float
    eq: object = field(default=None, repr=False)
    found_at: np.ndarray = field(default=None, repr=False)

    def elsewhere(self, angles):
        """True if slow rods at ``angles`` (None: not slow) are near neither this rest nor
        the state it was found from: they rest, or creep, by another equilibrium, and the
        candidate must be found again (rods that left an unstable equilibrium after the
        candidate was taken may come to rest in any well, and a whole turn away)."""
        if angles is None:
            return False
        angles = np.ravel(angles)
        return not any(np.max(np.abs(wrap(angles - np.ravel(ref)))) <= NEAR
                       for ref in (self.theta, self.found_at) if ref is not None)


@dataclass(frozen=True)
class RhoRamp:
    """rho(t): from ``rho0`` to ``rho1`` (floats, or one per module) at ``rate`` (m/s,
    > 0; the largest change sets the time, all actuators arrive together), then held."""

    rho0: object
    rho1: object
    rate: float
    duration: float = field(init=False)     # time (s) the ramp takes

    def __post_init__(self):
        for name in ('rho0', 'rho1', 'rate'):
            value = getattr(self, name)
            try:
                ok = bool(np.all(np.isfinite(np.asarray(value, dtype=float))))
            except (TypeError, ValueError):
                ok = False
            if not ok or isinstance(value, (str, bytes)):
                raise InvalidParameterError(f'{name} must be finite numbers, got {value!r}')
        if np.shape(self.rho0) != np.shape(self.rho1):
            raise InvalidParameterError(
                f'rho0 and rho1 differ in size: {np.shape(self.rho0)} vs {np.shape(self.rho1)}')
        if not self.rate > 0.0:
            raise InvalidParameterError(f'rate must be positive, got {self.rate!r}')
        # the right-hand side asks for it at every evaluation: computed once
        object.__setattr__(self, 'duration',
                           float(np.max(np.abs(np.subtract(self.rho1, self.rho0)))) / self.rate)

    def fraction(self, t):
        """Path parameter s in [0, 1] at time t (1 during the hold)."""
        duration = self.duration
        return 1.0 if duration == 0.0 or t >= duration else max(t, 0.0) / duration

    def rho(self, t):
        """rho at time(s) t: shape t.shape + rho0.shape."""
        if isinstance(t, float):        # one time, as the right-hand side asks: no arrays
            duration = self.duration
            s = 1.0 if duration == 0.0 else min(max(t / duration, 0.0), 1.0)
            return np.asarray(self.rho0, dtype=float) + s * np.subtract(self.rho1, self.rho0)
        t = np.asarray(t, dtype=float)
        duration = self.duration
        s = np.ones_like(t) if duration == 0.0 else np.clip(t / duration, 0.0, 1.0)
        s = s.reshape(s.shape + (1,) * np.ndim(self.rho0))
        return np.asarray(self.rho0, dtype=float) + s * np.subtract(self.rho1, self.rho0)

    def rho_dot(self, t):
        """d rho / dt at time t (zero during the hold)."""
        if t >= self.duration:
            return np.zeros_like(np.asarray(self.rho0, dtype=float))
        return np.subtract(self.rho1, self.rho0) / self.duration


@dataclass(frozen=True)
class SnapHistory:
    """Time history of a transient: ``t`` (s, n samples), ``rho`` (m), ``theta`` and
    ``theta_dot`` (rad, rad/s), ``actuator_force`` (N, inertia included).  One module:
    shapes (n,), (n, 2), (n, 2), (n,); a neck of N modules: (n, N), (n, N, 2), (n, N, 2),
    (n, N)."""

    t: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    actuator_force: np.ndarray


@dataclass(frozen=True)
class SolverSettings:
    """Integration settings: tolerances that keep the reported figures to 0.1 %.  Offline
    transients use solve_ivp's ``method``; the live loop (:mod:`.dynamics.live_motion`) VODE's
    Adams method with the same tolerances, sampled every ``sample`` s."""

    method: str = 'DOP853'
    rtol: float = 1e-10
    atol: float = 1e-12
    chunk: float = 1.0          # s of hold between checks for "settled for good"
    sample: float = 0.002       # s between the live loop's samples


def trapped(rest, y):
    """``rest`` if state ``y`` is below its threshold (trapped for good), else None."""
    if rest is not None and rest.excess(None, np.asarray(y)[None, :])[0] < rest.threshold:
        return rest
    return None


def checked_hold(hold):
    """``hold`` (s) as given, or InvalidParameterError."""
    if hold is not None and (not isinstance(hold, (int, float)) or not math.isfinite(hold)
                             or hold < 0.0):
        raise InvalidParameterError(f'hold must be finite and >= 0, got {hold!r}')
    return hold


def checked_damping(damping):
    if not isinstance(damping, (int, float)) or not math.isfinite(damping) or damping < 0.0:
        raise InvalidParameterError(f'damping must be finite and >= 0, got {damping!r}')
    return float(damping)


def _integrate(system, y0, t0, t1, settings, first_step=None):
    sol = solve_ivp(system.rhs, (t0, t1), y0, method=settings.method, rtol=settings.rtol,
                    atol=settings.atol, dense_output=True, events=system.onset_events(),
                    first_step=None if first_step is None else min(first_step, t1 - t0))
    if sol.status < 0:
        raise RuntimeError(f'the ODE solver failed: {sol.message}')
    return sol


def _step_size(sol):
    """The last full step of a solution (its very last one ends at the bound: cut short)."""
    steps = np.diff(sol.t)
    return float(steps[-2] if len(steps) > 1 else steps[-1]) if len(steps) else None


def run(system, y0, hold, settings):
    """Integrate the ramp, then the hold (``hold`` s, or until ``system.settled(y)``
    returns a :class:`Rest`, at most MAX_HOLD); returns (OdeSolution, onset events,
    Rest or None).  ``system.after_ramp(y)`` maps the state across the ramp's
    end, where the actuator velocities step to zero.

    The hold is integrated in chunks of ``settings.chunk`` s; each goes on with the step
    size the last one ended with.  (Left to choose its own first step, the solver takes a
    huge one from a state near rest -- tiny derivatives -- and its error estimate, fooled
    by the oscillation it steps over, accepts it: fig. 8a past C1, a kick of 3e-6 rad/s
    at t = 72 s that depended on the CPU's rounding.)"""
    ramp_end = system.ramp.duration
    pieces = []
    if ramp_end > 0.0:
        pieces.append(_integrate(system, y0, 0.0, ramp_end, settings))
        y0 = system.after_ramp(pieces[-1].y[:, -1])
    limit = MAX_HOLD if hold is None else hold
    t, settled = ramp_end, None
    while t < ramp_end + limit:
        t_next = min(t + settings.chunk, ramp_end + limit)
        step = _step_size(pieces[-1]) if pieces else None
        pieces.append(_integrate(system, y0, t, t_next, settings, step))
        t, y0 = t_next, pieces[-1].y[:, -1]
        settled = system.settled(y0)
        if settled is not None and hold is None:
            break
    ts = np.concatenate([pieces[0].t] + [p.t[1:] for p in pieces[1:]])
    interpolants = [f for p in pieces for f in p.sol.interpolants]
    events = [float(e) for p in pieces for ev in p.t_events for e in ev]
    return OdeSolution(ts, interpolants), events, settled


def sample_times(solution, per_step=4):
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


def _first_entry(f, ts, values):
    """The first time ``f`` (<= 0 inside) is <= 0, from its ``values`` at ``ts``, refined
    on the dense output (None if never)."""
    inside = np.flatnonzero(values <= 0.0)
    if inside.size == 0:
        return None
    i = int(inside[0])
    if i == 0:
        return float(ts[0])
    return float(brentq(f, ts[i - 1], ts[i], xtol=1e-12))


class _Continuous:
    """Angles read without the 2 pi jumps of wrapping: samples unwrapped along the time
    axis, and any time in between taken onto the branch of its nearest sample."""

    def __init__(self, angles, ts):
        self._angles, self.ts = angles, ts
        self.samples = np.unwrap(angles(ts), axis=0)

    def __call__(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        near = self.samples[np.clip(np.searchsorted(self.ts, t), 0, len(self.ts) - 1)]
        return near + wrap(self._angles(t) - near)

    def onto_branch(self, theta):
        """``theta`` shifted by whole turns onto the branch of the last sample."""
        last = self.samples[-1]
        return theta + 2.0 * math.pi * np.round((last - theta) / (2.0 * math.pi))


def figures(ts, angles, rates, forces, onset, rest, ramp_end, energy=None):
    """Peak speed, peak actuator force, overshoot and settling time of a transient.

    ``angles(t)``, ``rates(t)``, ``forces(t)`` evaluate the dense solution at an
    array of times (shape (n, k) for angles and rates, (n, m) for forces; angles may be
    wrapped: they are read continuously); ``onset`` is the onset time (or None),
    ``rest`` the :class:`Rest` (or None if not settled) and ``energy(t)`` its excess
    energy at times t >= ``ramp_end`` (rho held from there on).
    """
    angles = _Continuous(angles, ts)
    theta, omega, force = angles.samples, rates(ts), forces(ts)

    def at(f, t):
        return f(np.array([t]))[0]

    peak_speed = _refined_peak(lambda t: float(np.max(np.abs(at(rates, t)))), ts,
                               np.max(np.abs(omega), axis=1))
    sign = 1.0 if np.max(force) >= -np.min(force) else -1.0
    peak_force = sign * _refined_peak(lambda t: float(np.max(sign * at(forces, t))), ts,
                                      np.max(sign * force, axis=1))
    final = angles.onto_branch(rest.theta) if rest is not None else theta[-1]
    from_t = onset if onset is not None else 0.0
    overshoot = _overshoot(ts, theta, final, from_t, lambda t: at(angles, t))
    settle_time = None
    if rest is not None:
        held = ts >= ramp_end
        hold_ts = np.concatenate([[ramp_end], ts[held]])
        entry = _first_entry(lambda t: float(energy(np.array([t]))[0]) / rest.threshold - 1.0,
                             hold_ts, energy(hold_ts) / rest.threshold - 1.0)
        start = onset if onset is not None else ramp_end
        settle_time = None if entry is None else max(entry - start, 0.0)
    return {'peak_speed': peak_speed, 'peak_actuator_force': peak_force,
            'overshoot': overshoot, 'settle_time': settle_time, 'settled': rest is not None}


def _overshoot(ts, theta, final, from_t, angles_at):
    """Largest excursion (rad) of any rod past its final angle, away from where it came.

    Each rod approaches its final angle from the side it was on at ``from_t``
    (the onset, or the start); the overshoot is how far it swings beyond.  ``theta``
    and ``angles_at`` are continuous (unwrapped), ``final`` on the same branch.
    """
    keep = ts >= from_t
    if not np.any(keep):
        return 0.0
    direction = np.sign(final - angles_at(from_t))
    beyond = (theta[keep] - final) * direction
    worst = np.max(beyond, axis=0)
    rod = int(np.argmax(worst))
    if worst[rod] <= 0.0:
        return 0.0
    return max(_refined_peak(lambda t: float((angles_at(t)[rod] - final[rod]) * direction[rod]),
                             ts[keep], beyond[:, rod]), 0.0)


def wrap(angle):
    """Angles in [-pi, pi)."""
    return (np.asarray(angle, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi
