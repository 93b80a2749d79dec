"""Snap-through dynamics of one module (docs/model.md section 5).

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

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.integrate import OdeSolution

from . import transient
from .transient import (imperfection_torque, MAX_HOLD, NEAR, ONSET_SPEED, Rest, RhoRamp,
                        SAME_LANDING, SETTLE_TOLERANCE, SLOW, SnapHistory, SolverSettings,
                        wrap as _wrap)
from ..module import model as _m
from ..module.model import InvalidParameterError, ModuleParams
from ..module.tracking import ModulePath, ModuleTrack, settle, track_module


@dataclass(frozen=True)
class Snap:
    """Result of :func:`simulate_snap`: the history, the summary and the quasi-static
    prediction beside it.  ``static_fold_rho`` is the tracker's first jump (or None).

    ``summary`` keys: ``onset_rho`` (rho when either |theta'| first exceeds
    ONSET_SPEED, or None), ``onset_time``, ``peak_speed`` (rad/s), ``peak_actuator_force``
    (N, signed, largest magnitude), ``overshoot`` (rad past the final angle after the
    onset, on continuous angles), ``settle_time`` (s from the onset, or from the ramp's
    end if nothing snapped, until the energy above the rest state stays below the settled
    threshold: see :mod:`.dynamics.transient`; None if not settled), ``settled``, ``final``
    ({theta1, theta2, speed} at the end), ``quasi_static`` (the tracker's jumps and final
    state) and ``lands_elsewhere`` (the rest state is not the tracker's).
    """

    history: SnapHistory
    summary: dict
    quasi_static: ModuleTrack
    static_fold_rho: float | None
    solution: OdeSolution = field(repr=False)


class ModuleEquations:
    """The equations of motion of one module along a rho ramp.  ``extend_ramp``: the
    right-hand side continues the ramp at its rate past its end instead of holding (a live
    segment ends there; its integrator may step past the end only to interpolate)."""

    def __init__(self, params: ModuleParams, ramp: RhoRamp, damping: float,
                 extend_ramp=False):
        if params.m1 <= 0.0 or params.m2 <= 0.0:
            raise InvalidParameterError(
                f'dynamics needs positive rod masses, got m1={params.m1!r}, m2={params.m2!r}')
        self.start = params.with_(rho=ramp.rho0)
        self.end = params.with_(rho=ramp.rho1)
        self.path = ModulePath(self.start, self.end)
        self.ramp = ramp
        self.damping = transient.checked_damping(damping)
        self.inertia = np.array([params.m1 * params.L1 ** 2, params.m2 * params.L2 ** 2]) / 3.0
        self.extend_ramp = extend_ramp
        # the built-in imperfection (transient.IMPERFECTION) on rod 1
        self.imperfection = np.array([imperfection_torque(params), 0.0])
        self._constants = self._for_rhs(params, ramp)

    def _for_rhs(self, params, ramp):
        """The right-hand side's constants as floats: it runs some 2000 times per simulated
        second, so it is scalar arithmetic (a numpy call on two numbers costs more than
        the arithmetic)."""
        p = params
        rho0, rho1 = float(ramp.rho0), float(ramp.rho1)
        held_from = math.inf if self.extend_ramp else float(ramp.duration)
        return (rho0, rho1 - rho0, float(ramp.duration), held_from, p.L1 * (p.ka + p.kc),
                p.L2 * (p.kb + p.kc), p.kc * p.L1 * p.L2, p.L1 * p.f3x, p.L1 * p.f3y_total,
                p.L2 * p.f4x, p.L2 * p.f4y_total, float(self.imperfection[0]),
                self.damping, 1.0 / float(self.inertia[0]), 1.0 / float(self.inertia[1]))

    def rhs(self, t, y):
        """(theta', theta'') at time t: I theta'' = -dU/dtheta - c theta' (+ the imperfection)."""
        (rho0, drho, duration, held_from, a1, a2, kc12, f3x, f3y, f4x, f4y, tau, c, inv1,
         inv2) = self._constants
        rho = rho0 + drho if duration == 0.0 or t >= held_from else (
            rho0 + drho * max(t, 0.0) / duration)
        t1, t2, w1, w2 = y[0], y[1], y[2], y[3]
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        s12 = s1 * c2 + c1 * s2
        g1 = a1 * rho * s1 - kc12 * s12 + f3x * s1 - f3y * c1
        g2 = a2 * rho * s2 - kc12 * s12 - f4x * s2 - f4y * c2
        return np.array([w1, w2, (tau - g1 - c * w1) * inv1, (-g2 - c * w2) * inv2])

    def gradient(self, t, theta):
        """dU/dtheta at samples (t, theta): vectorised on the hold, per sample on the ramp."""
        theta = np.atleast_2d(theta)
        out = _m.gradient(self.end, theta)
        for i in np.flatnonzero(np.asarray(t) < self.ramp.duration):
            out[i] = self.path.residual(theta[i], self.ramp.fraction(t[i]))
        return out

    def acceleration(self, t, y):
        """theta'' at samples; ``y`` has shape (n, 4)."""
        return (self.imperfection - self.gradient(t, y[:, :2])
                - self.damping * y[:, 2:]) / self.inertia

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

    @staticmethod
    def after_ramp(y):
        """The angle rates carry on when rho stops (its rho'' impulse is neglected)."""
        return y

    @staticmethod
    def onset_events():
        """Event functions: either rod's |theta'| crosses ONSET_SPEED."""
        def rod1(t, y):
            return y[2] * y[2] - ONSET_SPEED ** 2

        def rod2(t, y):
            return y[3] * y[3] - ONSET_SPEED ** 2

        return [rod1, rod2]

    def slow_angles(self, t, y):
        """The angles of state ``y`` if both rods are slower than SLOW, else None (scalar
        tests: asked at every tick of the live loop)."""
        if abs(float(y[2])) > SLOW or abs(float(y[3])) > SLOW:
            return None
        return np.array(y[:2], dtype=float)

    def rest_candidate(self, y, known=None):
        """The :class:`~.dynamics.transient.Rest` of the equilibrium a slow state (|theta'| below
        SLOW) is settling to, or None (fast, undamped, or no equilibrium found).
        ``known``: a verified equilibrium at rho1 taken if the state is within NEAR of
        it (the quasi-static prediction: no second settle)."""
        angles = self.slow_angles(None, y)
        if self.damping == 0.0 or angles is None:
            return None
        eq = known
        if eq is None or np.max(np.abs(_wrap(angles - np.ravel(eq.theta)))) > NEAR:
            try:
                eq = settle(self.end, angles)
            except (RuntimeError, ValueError):
                return None
        theta_eq = eq.theta + 2.0 * math.pi * np.round((angles - eq.theta) / (2.0 * math.pi))
        return Rest(theta=theta_eq, excess=self.excess_energy(theta_eq),
                    threshold=0.5 * min(float(np.min(eq.eigenvalues)),
                                        float(np.min(self.inertia))) * SETTLE_TOLERANCE ** 2,
                    eq=eq, found_at=angles.copy())

    def settled(self, y):
        """The :class:`~.dynamics.transient.Rest` if the state is trapped within SETTLE_TOLERANCE
        for good, else None.

        With damping the mechanical energy never grows while rho is held, so once it
        is below the least energy any state outside the tolerance box has (half the
        smallest of the Hessian's eigenvalues and the inertias, times tol^2), the
        motion stays in the box for good.
        """
        rest = self.rest_candidate(y)
        return transient.trapped(rest, y)

    def excess_energy(self, theta_eq):
        """Energy (J) above the minimum ``theta_eq`` at rho1 of states (n, 4): kinetic plus
        the quadratic potential about it (exact to third order in the distance, and free
        of the cancellation of two large potentials), on the angles' differences modulo
        2 pi (the potential is periodic in each angle: a rod at rest a whole turn from
        ``theta_eq`` is at rest there)."""
        h = _m.hessian(self.end, theta_eq)

        def excess(t, ys):
            delta = _wrap(ys[:, :2] - theta_eq)
            potential = np.einsum('ni,ij,nj->n', delta, h, delta)
            return 0.5 * (ys[:, 2:] ** 2 @ self.inertia + potential)
        return excess


def _beside_quasi_static(track, final_theta):
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
    transient.checked_hold(hold)
    ramp = RhoRamp(float(params.rho), float(rho_end), float(rate))
    system = ModuleEquations(params, ramp, damping)
    start = settle(system.start, theta_guess)
    solution, events, rest = transient.run(system, np.array([*start.theta, 0.0, 0.0]), hold,
                                           settings)
    ts = transient.sample_times(solution)
    y = solution(ts).T
    history = SnapHistory(t=ts, rho=ramp.rho(ts), theta=y[:, :2].copy(),
                          theta_dot=y[:, 2:].copy(), actuator_force=system.actuator_force(ts, y))
    track = track_module(system.start, system.end, start.theta)
    fold = float(track.jumps[0].params.rho) if track.jumps else None
    return Snap(history=history, summary=_summary(system, solution, history, events, rest, track),
                quasi_static=track, static_fold_rho=fold, solution=solution)


def _summary(system, solution, history, events, rest, track):
    """The issue's figures of the run, the final state, the quasi-static prediction."""
    ramp = system.ramp
    onset = min(events) if events else None
    summary = {'onset_rho': None if onset is None else float(ramp.rho(onset)),
               'onset_time': onset}
    summary.update(transient.figures(
        history.t, lambda t: solution(t).T[:, :2], lambda t: solution(t).T[:, 2:],
        lambda t: system.actuator_force(t, solution(t).T)[:, None], onset, rest,
        ramp.duration, energy=None if rest is None else (lambda t: rest.excess(t, solution(t).T))))
    theta, speed = history.theta[-1], history.theta_dot[-1]
    summary['final'] = {'theta1': float(_wrap(theta[0])), 'theta2': float(_wrap(theta[1])),
                        'speed': float(np.max(np.abs(speed)))}
    summary.update(_beside_quasi_static(track, rest.theta if rest is not None else theta))
    return summary


__all__ = ['RhoRamp', 'SnapHistory', 'Snap', 'SolverSettings', 'simulate_snap',
           'ONSET_SPEED', 'SETTLE_TOLERANCE', 'MAX_HOLD']
