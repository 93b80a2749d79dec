"""A mechanism in motion, driven in real time: the loop one module and a neck share.

:class:`LiveMotion` keeps the state between calls.  ``command`` sets new actuator
targets at a given time; rho then runs towards them at the speed limit, from wherever
it is, while the rods keep their momentum (a command arriving during a transient acts
on the moving mechanism).  ``advance`` integrates up to a time with scipy's
``solve_ivp`` in segments: a segment is one :class:`~.transient.RhoRamp` (from the
current rho to the targets, then held) with the equations a subclass builds
(:mod:`.moving_module`: one module in its angles; :mod:`.moving_neck`: N modules in
node coordinates).  When a snap (any |theta'| above ONSET_SPEED) has come to rest,
``advance`` returns its figures, the keys of the offline transients' summaries, read
from the same dense output.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp

from . import transient
from .module import InvalidParameterError
from .transient import SolverSettings


class LiveMotion:
    """The shared integration loop; a subclass says what the state and equations are.

    Subclass hooks: ``_equations()`` (the segment's equations from ``params``, ``rho``,
    ``target``, ``max_rate``, ``damping``), ``_carried(old, t_local, y, new)`` (the state
    across a segment boundary; ``old`` None: ``y`` is the ``start`` given, at rest),
    ``_readings(system, t_local, ys)`` (angles and rates of samples),
    ``_forces(system, t_local, ys)``, ``_final(y)``, ``_checked_target(target)``,
    ``_checked_rate(rate)``, ``_checked_damping(damping)`` and ``_rho_of(array)``.
    """

    def __init__(self, params, rho, start, damping, max_rate, t: float = 0.0,
                 settings: SolverSettings = SolverSettings()):
        self.params, self.settings = params, settings
        self.max_rate = self._checked_rate(max_rate)
        self.damping = self._checked_damping(damping)
        self.t = float(t)
        self.rho = self.target = rho
        self.y = start                 # what _carried(None, ...) turns into the first state
        self._system = None
        self._record = None            # the snap under way: segments, interpolants, events
        self._at_rest = True
        self._segment(self.t)

    @property
    def moving(self):
        """True until the rods are at rest (within SETTLE_TOLERANCE for good) at the
        target."""
        return not self._at_rest

    def _local(self):
        """Time since the current segment started."""
        return self.t - self._t0

    # -- driving it ----------------------------------------------------------------------
    def command(self, rho_target, t):
        """Move towards ``rho_target`` from time ``t`` on (after advancing to ``t``).

        Returns what :meth:`advance` returned on the way.  A bad target raises
        InvalidParameterError and changes nothing.
        """
        target = self._checked_target(rho_target)
        reports = self.advance(t)
        if target != self.target:
            self.target, self._at_rest = target, False
            self._segment(self.t)
        return reports

    def advance(self, t):
        """Integrate up to time ``t``; returns the figures of every snap that came to rest."""
        if not t >= self.t:
            raise InvalidParameterError(f'time must not go back: at {self.t!r}, got {t!r}')
        if self._at_rest:               # settled for good (see the equations' settled)
            self.t = float(t)
            return []
        reports = []
        while self.t < t:
            ramp_end = self._t0 + self._system.ramp.duration
            stop = min(t, ramp_end) if self.t < ramp_end else t
            self._integrate(stop)
            if self.t >= ramp_end and self._system.ramp.duration > 0.0:
                # the ramp's end (even where its last rho rounds to the target): held from
                # here, and the state crosses the actuators' velocity step (_carried)
                self.rho = self.target
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
                self.max_rate = self._checked_rate(max_rate)
            if damping is not None:
                self.damping, self._at_rest = self._checked_damping(damping), False
            self._segment(self.t)
        except InvalidParameterError:
            self.params, self.max_rate, self.damping, self._at_rest = old
            raise
        return reports

    # -- internals -----------------------------------------------------------------------
    def _segment(self, t0):
        """Equations for rho running from its current value to the target from t0 on; the
        state is carried over from the last segment (or started at rest)."""
        system = self._equations()
        y = self._carried(self._system, self.t - self._t0 if self._system else 0.0, self.y,
                          system)
        self._t0, self._system, self.y = t0, system, y  # only once all of it could be built
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
            self._record = {'onset': min(onsets),
                            'rho': self._rho_of(system.ramp.rho(min(onsets) - t0)),
                            'segments': [(t0, system)], 'ts': [self.t], 'interpolants': []}
        if self._record is not None:
            self._record['ts'].extend(sol.t[1:].tolist())
            self._record['interpolants'].extend(sol.sol.interpolants)
        self.t, self.y = float(stop), sol.y[:, -1]
        self.rho = self._rho_of(system.ramp.rho(self.t - t0))

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
        segments = record['segments']
        starts = np.array([s[0] for s in segments])

        def by_segment(read):
            def evaluate(t):
                t = np.atleast_1d(np.asarray(t, dtype=float))
                ys = solution(t).T
                which = np.maximum(np.searchsorted(starts, t, 'right') - 1, 0)
                parts = {k: read(segments[k][1], t[which == k] - segments[k][0],
                                 ys[which == k]) for k in np.unique(which)}
                out = np.empty((len(t), next(iter(parts.values())).shape[1]))
                for k, part in parts.items():
                    out[which == k] = part
                return out
            return evaluate

        ts = transient.sample_times(solution)
        last_t0, last = segments[-1]
        held_from = max(last_t0 + last.ramp.duration, record['onset'])

        def energy(t):
            return rest.excess(t - last_t0, solution(t).T)

        report = {'onset_rho': record['rho'], 'onset_time': record['onset']}
        report.update(transient.figures(
            ts, by_segment(lambda s, t, y: self._readings(s, t, y)[0]),
            by_segment(lambda s, t, y: self._readings(s, t, y)[1]),
            by_segment(self._forces), record['onset'], rest, held_from, energy=energy))
        report['final'] = self.final_state()
        return report

    def final_state(self):
        """The state now as a summary's ``final`` (angles and the fastest rate)."""
        return self._final(self.y)
