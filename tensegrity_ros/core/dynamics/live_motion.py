"""A mechanism in motion, driven in real time: the loop one module and a neck share.

:class:`LiveMotion` keeps the state between calls.  ``command`` sets new actuator
targets from a given time; rho then runs towards them at the speed limit, from wherever
it is, while the rods keep their momentum (a command arriving during a transient acts
on the moving mechanism).  ``advance`` integrates up to a time in segments: a segment is
one :class:`~.dynamics.transient.RhoRamp` (from the current rho to the targets, then held) with
the equations a subclass builds (:mod:`.dynamics.moving_module`: one module in its angles;
:mod:`.dynamics.moving_neck`: N modules in node coordinates).

Integration: scipy's VODE (Adams, compiled) runs on through the ticks without restarting
and interpolates the state at every sample time (a grid of ``settings.sample`` s) and at
the end of each call; it restarts only where the right-hand side changes (a ramp's end, a
command, a change).  Adams needs 1-2 right-hand sides a step where the explicit
Runge-Kutta pairs need 8-12, on these smooth, lightly damped (non-stiff) motions.

Bounded work: ``advance(t, deadline, clock)`` stops at the first sample past
``deadline`` (in ``clock`` units); ``t`` is then later than :attr:`t`, the time the state
holds for, and the next call goes on from there.  Commands and changes given for a time
the integration has not reached wait in a queue and act at their own time.

When a snap (any |theta'| above ONSET_SPEED) has come to rest, ``advance`` returns its
figures, the keys of the offline transients' summaries: read on the samples and refined
(peaks, the onset, the settling time) on a short dense re-integration from the sample
before (DOP853, rtol 1e-12), so that they do not depend on the sample spacing.
"""
from __future__ import annotations

import functools
import math
import time

import numpy as np
from scipy.integrate import ode, solve_ivp
from scipy.optimize import brentq

from . import transient
from .transient import ONSET_SPEED, SolverSettings
from ..module.model import InvalidParameterError
from ..numerics.bounded_work import checkpoint

#: Tolerances of the short re-integrations that refine a snap's figures.
REFINE_RTOL, REFINE_ATOL = 1e-12, 1e-14


class LiveMotion:
    """The shared integration loop; a subclass says what the state and equations are.

    Subclass hooks: ``_equations()`` (the segment's equations from ``params``, ``rho``,
    ``target``, ``max_rate``, ``damping``), ``_carried(old, t_local, y, new)`` (the state
    across a segment boundary; ``old`` None: ``y`` is the ``start`` given, at rest),
    ``_all_readings(system, t_local, ys)`` (angles, rates and actuator forces of samples,
    2-d arrays), ``_reading_splits()`` (where they part when stacked side by side),
    ``_fastest(system, t_local, y)`` (the largest
    |theta'| of one state), ``_final(y)``, ``_checked_target(target)``,
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
        self._record = None            # the snap under way (a _Record)
        self._at_rest = True
        self._rest = None              # the segment's Rest candidate (see _now_at_rest)
        self._queue = []               # (time, kind, values): changes not yet reached
        self._last_sample = None       # (t, y, segment) of the last sample taken
        #: A verified equilibrium at the parameters held now (set by the caller; dropped at
        #: any command or change): the rest is taken there if the rods come to rest by it.
        self.rest_hint = None
        #: advance() returns a snap's figures as a function of no arguments that computes
        #: them (a caller that bounds its work runs it in slices: it has check points).
        self.lazy_reports = False
        self._segment(self.t)

    @property
    def moving(self):
        """True until the rods are at rest (within SETTLE_TOLERANCE for good) at the
        target, with no change waiting."""
        return not self._at_rest or bool(self._queue)

    def _local(self):
        """Time since the current segment started."""
        return self.t - self._t0

    def latest(self, name):
        """``target``, ``params``, ``max_rate`` or ``damping`` as the last command or change
        given sets it (queued ones included)."""
        for _, kind, values in reversed(self._queue):
            if name == 'target' and kind == 'target':
                return values
            if name != 'target' and kind == 'change' and values[name] is not None:
                return values[name]
        return getattr(self, name)

    # -- driving it ----------------------------------------------------------------------
    def command(self, rho_target, t, deadline=math.inf, clock=time.process_time):
        """Move towards ``rho_target`` from time ``t`` on.

        Returns what :meth:`advance` (to ``t``, within ``deadline``) returned on the way;
        if it did not reach ``t`` the command waits and acts at ``t``.  A bad target
        raises InvalidParameterError and changes nothing.
        """
        target = self._checked_target(rho_target)
        self._queue_change(t, 'target', target)
        return self.advance(t, deadline, clock)

    def change(self, t, params=None, max_rate=None, damping=None, deadline=math.inf,
               clock=time.process_time):
        """New design or loads (``params``; its rho is ignored), speed limit or damping from
        time ``t`` on: the rods move on from where they are.

        Returns what :meth:`advance` returned on the way.  Bad values (e.g. a mass of 0)
        raise InvalidParameterError and change nothing.
        """
        values = {'params': params, 'max_rate': None if max_rate is None else
                  self._checked_rate(max_rate), 'damping': None if damping is None else
                  self._checked_damping(damping)}
        if params is not None:
            self._trial(params)
        self._queue_change(t, 'change', values)
        return self.advance(t, deadline, clock)

    def advance(self, t, deadline=math.inf, clock=time.process_time):
        """Integrate towards time ``t`` until ``deadline`` (``clock`` units): returns the
        figures of every snap that came to rest.  :attr:`t` is where it got to."""
        if not t >= self.t:
            raise InvalidParameterError(f'time must not go back: at {self.t!r}, got {t!r}')
        reports = []
        while self.t < t or self._due():
            self._apply_due()
            if self._at_rest:           # settled for good: the state holds until a change
                self.t = float(min(t, self._queue[0][0])) if self._queue else float(t)
                continue
            stop = min(t, self._queue[0][0] if self._queue else math.inf)
            ramp_end = self._t0 + self._system.ramp.duration
            if self.t < ramp_end:
                stop = min(stop, ramp_end)
            if not self._integrate(stop, deadline, clock):
                break                                   # out of time: the next call goes on
            if self.t >= ramp_end and self._system.ramp.duration > 0.0:
                self.rho = self.target                  # held from here (_carried)
                self._segment(self.t)
            if not self._due() and self._now_at_rest():
                report = self._rest_report()
                if report is not None:
                    reports.append(report)
        return reports

    # -- the queue -----------------------------------------------------------------------
    def _queue_change(self, t, kind, values):
        if not t >= self.t:
            raise InvalidParameterError(f'time must not go back: at {self.t!r}, got {t!r}')
        self._queue.append((float(t), kind, values))
        self._queue.sort(key=lambda entry: entry[0])

    def _due(self):
        return bool(self._queue) and self._queue[0][0] <= self.t

    def _apply_due(self):
        """Apply every queued change whose time the integration has reached."""
        while self._due():
            _, kind, values = self._queue.pop(0)
            self.rest_hint = None
            if kind == 'target':
                if values != self.target:
                    self.target, self._at_rest = values, False
                    self._segment(self.t)
                continue
            if values['params'] is not None:
                self.params, self._at_rest = values['params'], False
            if values['max_rate'] is not None:
                self.max_rate = values['max_rate']
            if values['damping'] is not None:
                self.damping, self._at_rest = values['damping'], False
            self._segment(self.t)

    def _trial(self, params):
        """Raise InvalidParameterError if ``params`` cannot be simulated (built, not kept)."""
        kept = self.params
        try:
            self.params = params
            self._equations()
        finally:
            self.params = kept

    # -- integration ---------------------------------------------------------------------
    def _segment(self, t0):
        """Equations for rho running from its current value to the target from t0 on; the
        state is carried over from the last segment (or started at rest)."""
        system = self._equations()
        y = self._carried(self._system, self.t - self._t0 if self._system else 0.0, self.y,
                          system)
        self._t0, self._system, self.y = t0, system, y  # only once all of it could be built
        self._rest = None
        self._solver = None                             # made when first needed
        self._last_sample = (self.t, self.y, system, t0)
        if self._record is not None:
            self._record.segments.append((t0, system))
            self._record.add(self._last_sample)

    def _make_solver(self):
        s = self.settings
        solver = ode(self._system.rhs).set_integrator('vode', method='adams', rtol=s.rtol,
                                                      atol=s.atol, nsteps=100000)
        solver.set_initial_value(self.y, self.t - self._t0)
        return solver

    def _integrate(self, stop, deadline, clock):
        """Integrate the segment to ``stop`` sample by sample; False if out of time first."""
        if self._solver is None:
            self._solver = self._make_solver()
        sample = self.settings.sample
        while self.t < stop:
            t_next = min(stop, (math.floor(self.t / sample + 1e-9) + 1) * sample)
            y = self._solver.integrate(t_next - self._t0)
            if not self._solver.successful():
                raise RuntimeError(f'the ODE solver failed at t={self.t!r}')
            self.t, self.y = t_next, y.copy()
            self._sampled()
            if self.t < stop and clock() > deadline:
                break
        self.rho = self._rho_of(self._system.ramp.rho(self.t - self._t0))
        return self.t >= stop

    def _sampled(self):
        """Keep the sample; start a snap's record at the first sample past ONSET_SPEED."""
        sample = (self.t, self.y, self._system, self._t0)
        if self._record is None:
            if self._fastest(self._system, self.t - self._t0, self.y) > ONSET_SPEED:
                self._record = _Record(self._last_sample, self._t0, self._system)
        if self._record is not None:
            self._record.add(sample)
        self._last_sample = sample

    # -- rest and the report ---------------------------------------------------------------
    def _now_at_rest(self):
        """True on the call at which the rods come to rest at the held target.

        The rest equilibrium is found from a slow state (settling is the costly part) and
        then only the energy above it is checked, modulo 2 pi.  It is found again where
        slow rods are near neither it nor the state it was found from: taken while they
        crept on an unstable branch, it need not be where they come to rest."""
        if self._at_rest or self.rho != self.target:
            return False
        angles = self._system.slow_angles(self.t - self._t0, self.y)
        if angles is None:
            return False                # (trapped rods are far slower than SLOW)
        rest = self._rest
        if rest is not None:
            if transient.trapped(rest, self.y) is not None:
                self._at_rest = True
                return True
            if not rest.elsewhere(angles):
                return False
        rest = self._system.rest_candidate(self.y, known=self.rest_hint)
        if rest is None:
            return False
        self._rest = rest
        self._at_rest = transient.trapped(rest, self.y) is not None
        return self._at_rest

    def _rest_report(self):
        """The figures of the snap that has just come to rest (None if nothing snapped);
        with ``lazy_reports`` the function that computes them."""
        record, rest = self._record, self._rest
        if record is None:
            return None
        self._record = None
        report = functools.partial(record.figures, self, rest, self.final_state())
        return report if self.lazy_reports else report()

    @property
    def has_queued(self):
        """True while a command or change waits for the integration to reach its time."""
        return bool(self._queue)

    @property
    def rest(self):
        """The :class:`~.dynamics.transient.Rest` the rods are at (None while they move)."""
        return self._rest if self._at_rest else None

    def final_state(self):
        """The state now as a summary's ``final`` (angles and the fastest rate)."""
        return self._final(self.y)


class _Record:
    """The samples of a snap under way (from the sample before its onset) and their
    segments, with dense re-integrations from a sample on demand."""

    def __init__(self, before, t0, system):
        self.samples = [before]
        self.segments = [(before[3], before[2])]
        self._dense = {}

    def add(self, sample):
        self.samples.append(sample)

    def _dense_from(self, k):
        """A dense solution from sample k to the next (its segment's equations)."""
        found = self._dense.get(k)
        if found is None:
            t, y, system, t0 = self.samples[k]
            t_end = self.samples[k + 1][0]
            found = solve_ivp(system.rhs, (t - t0, t_end - t0), y, method='DOP853',
                              rtol=REFINE_RTOL, atol=REFINE_ATOL, dense_output=True).sol
            self._dense[k] = found
        return found

    def reader(self, read, at_samples=None):
        """f(t array) -> read(system, t_local, ys) rows: the samples at sample times, a
        dense re-integration from the sample before anywhere else; one call of ``read``
        per segment.  ``at_samples``: the rows at every sample, computed once, returned
        when f is asked for exactly the sample times."""
        times = np.array([s[0] for s in self.samples])
        states = np.array([s[1] for s in self.samples])
        segment_of = {}
        which = np.array([segment_of.setdefault(id(s[2]), len(segment_of))
                          for s in self.samples])

        def evaluate(t):
            checkpoint()                    # the figures may be worked off in slices
            t = np.atleast_1d(np.asarray(t, dtype=float))
            if at_samples is not None and t.shape == times.shape and np.array_equal(t, times):
                return at_samples
            k = np.clip(np.searchsorted(times, t, 'right') - 1, 0, len(times) - 1)
            ys = states[k].copy()
            for j in np.flatnonzero((times[k] != t) & (k + 1 < len(times))):
                ys[j] = self._dense_from(int(k[j]))(t[j] - self.samples[k[j]][3])
            rows = None
            for seg in np.unique(which[k]):
                here = which[k] == seg
                first = self.samples[int(k[np.argmax(here)])]
                part = read(first[2], t[here] - first[3], ys[here])
                if rows is None:
                    rows = np.empty((len(t),) + np.shape(part)[1:])
                rows[here] = part
            return rows
        return evaluate

    def figures(self, motion, rest, final):
        """The snap's figures (the keys of the offline summaries); ``final`` the state at
        rest (:meth:`LiveMotion.final_state`)."""
        times = np.array([s[0] for s in self.samples])
        table = self.reader(lambda s, t, y: np.hstack(motion._all_readings(s, t, y)))(times)
        angles_at, rates_at, forces_at = np.split(table, motion._reading_splits(), axis=1)
        rates = self.reader(lambda s, t, y: motion._all_readings(s, t, y)[1], rates_at)
        onset = self._onset(rates, times)
        last_t0, last = self.segments[-1]
        held_from = max(last_t0 + last.ramp.duration, onset)
        state = self.reader(lambda s, t, y: y)
        system, t0 = self._system_at(onset)
        report = {'onset_rho': motion._rho_of(system.ramp.rho(onset - t0)), 'onset_time': onset}
        report.update(transient.figures(
            times, self.reader(lambda s, t, y: motion._all_readings(s, t, y)[0], angles_at),
            rates, self.reader(lambda s, t, y: motion._all_readings(s, t, y)[2], forces_at),
            onset, rest, held_from, energy=lambda t: rest.excess(t - last_t0, state(t))))
        report['final'] = final
        return report

    def _system_at(self, t):
        starts = [t0 for t0, _ in self.segments]
        k = max(int(np.searchsorted(starts, t, 'right')) - 1, 0)
        return self.segments[k][1], self.segments[k][0]

    def _onset(self, rates, times):
        """The first time any |theta'| reaches ONSET_SPEED (between the first two samples)."""
        def excess(t):
            return float(np.max(np.abs(rates(t)[0]))) - ONSET_SPEED
        if excess(times[0]) >= 0.0:
            return float(times[0])
        return float(brentq(excess, times[0], times[1], xtol=1e-13))
