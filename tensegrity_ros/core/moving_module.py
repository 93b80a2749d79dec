"""One module in motion, driven in real time (the ROS-free half of the node's ``dynamics``).

:class:`MovingModule` keeps the rods' angles and rates between calls.  ``command``
sets a new actuator target at a given time; rho then runs towards it at the speed
limit, from wherever it is, while the rods keep their momentum (a command arriving
during a transient acts on the moving mechanism).  ``advance`` integrates up to a
time with the equations of :mod:`.dynamics`.  When a snap (either |theta'| above
ONSET_SPEED) has come to rest, ``advance`` returns its figures, the keys of
:func:`~.dynamics.simulate_snap`'s summary read from the same dense output.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp

from . import transient
from .dynamics import ModuleEquations
from .module import InvalidParameterError, ModuleParams
from .tracking import settle
from .transient import RhoRamp, SolverSettings, wrap


def _checked_rate(max_rate):
    if not isinstance(max_rate, (int, float)) or not 0.0 < max_rate < math.inf:
        raise InvalidParameterError(f'max_rate must be positive and finite, got {max_rate!r}')
    return float(max_rate)


class MovingModule:
    """A module with rod masses ``params.m1``, ``m2``, pivot ``damping`` (N m s/rad) and an
    actuator speed limit ``max_rate`` (m/s), at rest at time ``t`` in the stable
    equilibrium whose basin holds ``theta_guess``."""

    def __init__(self, params: ModuleParams, theta_guess, damping: float, max_rate: float,
                 t: float = 0.0, settings: SolverSettings = SolverSettings()):
        self.params, self.max_rate, self.settings = params, _checked_rate(max_rate), settings
        self.damping = transient.checked_damping(damping)
        start = settle(params, theta_guess)
        self.t = float(t)
        self.y = np.array([*start.theta, 0.0, 0.0])
        self.rho = self.target = float(params.rho)
        self._record = None            # the snap under way: segments, interpolants, events
        self._at_rest = True
        self._segment(self.t)

    # -- what it is now ----------------------------------------------------------------
    @property
    def theta(self):
        return wrap(self.y[:2])

    @property
    def theta_dot(self):
        return self.y[2:].copy()

    @property
    def actuator_force(self):
        """Force (N) on A2 along +x now, rod 2's inertia included."""
        return float(self._system.actuator_force(np.array([self.t - self._t0]),
                                                 self.y[None, :])[0])

    @property
    def rho_dot(self):
        """Actuator speed (m/s) now: the speed limit towards the target, 0 when there."""
        return float(self._system.ramp.rho_dot(self.t - self._t0))

    @property
    def moving(self):
        """True until the rods are at rest (within SETTLE_TOLERANCE for good) at the
        target."""
        return not self._at_rest

    # -- driving it ----------------------------------------------------------------------
    def command(self, rho_target, t):
        """Move towards ``rho_target`` from time ``t`` on (after advancing to ``t``).

        Returns what :meth:`advance` returned on the way.  A bad target raises
        InvalidParameterError and changes nothing.
        """
        try:
            target = float(rho_target)
        except (TypeError, ValueError):
            raise InvalidParameterError(f'rho target must be a number, '
                                        f'got {rho_target!r}') from None
        self.params.with_(rho=target)                 # validates (finite, positive, range)
        reports = self.advance(t)
        if target != self.target:
            self.target, self._at_rest = target, False
            self._segment(self.t)
        return reports

    def advance(self, t):
        """Integrate up to time ``t``; returns the figures of every snap that came to rest."""
        if not t >= self.t:
            raise InvalidParameterError(f'time must not go back: at {self.t!r}, got {t!r}')
        if self._at_rest:               # settled for good (see ModuleEquations.settled)
            self.t = float(t)
            return []
        reports = []
        while self.t < t:
            ramp_end = self._t0 + self._system.ramp.duration
            stop = min(t, ramp_end) if self.t < ramp_end else t
            self._integrate(stop)
            if self.t >= ramp_end and self.rho != self.target:
                self.rho = self.target                 # the ramp's end: held from here
                self._segment(self.t)
            report = self._rest_report() if self._now_at_rest() else None
            if report is not None:
                reports.append(report)
        return reports

    def change(self, t, params=None, max_rate=None, damping=None):
        """New design or loads (``params``; its rho is ignored), speed limit or damping from
        time ``t`` on (after advancing to ``t``): the rods move on from where they are.

        Returns what :meth:`advance` returned on the way.  Bad values (e.g. a mass of 0)
        raise InvalidParameterError and change nothing.
        """
        reports = self.advance(t)
        old = self.params, self.max_rate, self.damping, self._at_rest
        try:
            if params is not None:
                self.params, self._at_rest = params, False
            if max_rate is not None:
                self.max_rate = _checked_rate(max_rate)
            if damping is not None:
                self.damping, self._at_rest = transient.checked_damping(damping), False
            self._segment(self.t)
        except InvalidParameterError:
            self.params, self.max_rate, self.damping, self._at_rest = old
            raise
        return reports

    # -- internals -----------------------------------------------------------------------
    def _segment(self, t0):
        """Equations for rho running from its current value to the target from t0 on."""
        system = ModuleEquations(self.params.with_(rho=self.rho),
                                 RhoRamp(self.rho, self.target, self.max_rate), self.damping)
        self._t0, self._system = t0, system      # only once the equations could be built
        if self._record is not None:
            self._record['segments'].append((t0, self._system))

    def _integrate(self, stop):
        system, t0 = self._system, self._t0
        sol = solve_ivp(lambda t, y: system.rhs(t - t0, y), (self.t, stop), self.y,
                        method=self.settings.method, rtol=self.settings.rtol,
                        atol=self.settings.atol, dense_output=True,
                        events=system.onset_events())
        if sol.status < 0:
            raise RuntimeError(f'the ODE solver failed: {sol.message}')
        onsets = [float(e) for ev in sol.t_events for e in ev]
        if self._record is None and onsets:
            self._record = {'onset': min(onsets), 'rho': float(system.ramp.rho(min(onsets) - t0)),
                            'segments': [(t0, system)], 'ts': [self.t], 'interpolants': []}
        if self._record is not None:
            self._record['ts'].extend(sol.t[1:].tolist())
            self._record['interpolants'].extend(sol.sol.interpolants)
        self.t, self.y = float(stop), sol.y[:, -1]
        self.rho = float(system.ramp.rho(self.t - t0))

    def _now_at_rest(self):
        """True on the call at which the rods come to rest at the held target."""
        if self._at_rest or self.rho != self.target:
            return False
        self._rest = self._system.settled(self.y)
        self._at_rest = self._rest is not None
        return self._at_rest

    def _rest_report(self):
        """The figures of the snap that has just come to rest (None if nothing snapped)."""
        record, rest = self._record, self._rest
        if record is None:
            return None
        self._record = None
        solution = OdeSolution(np.array(record['ts']), record['interpolants'])
        starts = np.array([s[0] for s in record['segments']])

        def forces(t):
            t = np.atleast_1d(t)
            y = solution(t).T
            out = np.empty(len(t))
            for k, (t_k, y_k) in enumerate(zip(t, y)):
                t0, system = record['segments'][max(np.searchsorted(starts, t_k, 'right') - 1, 0)]
                out[k] = system.actuator_force(np.array([t_k - t0]), y_k[None, :])[0]
            return out[:, None]

        ts = transient.sample_times(solution)
        report = {'onset_rho': record['rho'], 'onset_time': record['onset']}
        report.update(transient.figures(ts, lambda t: solution(t).T[:, :2],
                                        lambda t: solution(t).T[:, 2:], forces,
                                        record['onset'], rest, record['onset']))
        report['final'] = {'theta1': float(wrap(self.y[0])), 'theta2': float(wrap(self.y[1])),
                           'speed': float(np.max(np.abs(self.y[2:])))}
        return report
