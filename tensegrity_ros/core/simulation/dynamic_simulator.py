"""The simulator in dynamics mode (docs/model.md section 5): the rods move in real time.

:class:`DynamicSimulator` has the :class:`~.simulation.simulator.Simulator` interface, but a
command does not jump the state to the end of a tracked path: the actuators run at
their speed limits and the rods follow with their inertia, integrated up to each call's
time (:class:`~.dynamics.moving_module.MovingModule` for one module,
:class:`~.dynamics.moving_neck.MovingNeck` for a neck: one loop,
:class:`~.dynamics.live_motion.LiveMotion`).
Commands, loads and parameter changes during a transient act on the moving rods.  While
the rods move the state is not a verified equilibrium (``stable`` is False, ``status`` is
``warn`` "in motion"); when they come to rest, the rest state is verified (settled,
positive definite) and becomes the simulator's state, and a snap on the way is a
:class:`~.simulation.events.Jump` whose ``dynamics`` holds the figures (onset_rho, peak_speed,
peak_actuator_force, overshoot, settle_time, final) beside the quasi-static prediction.

Bounded work, as in the quasi-static mode: a call works at most ``time_budget`` seconds
(of ``clock``).  The integration stops at the first sample past it: the live state then
holds for an earlier time than the call's (:attr:`DynamicSimulator.state_time_ns`),
:attr:`~DynamicSimulator.lag` says by how much and the next calls catch up.  Commands and
changes act at their own time even when the integration has not reached it yet.  The
verification of a rest state and the quasi-static prediction beside its jump, the path
tracked ahead for an early warning and a reset's settle go on over several calls the same
way (:mod:`.numerics.bounded_work`).

Early warnings (:class:`~.simulation.events.JumpAhead`), by the quasi-static mode's rule: a fold
(or a buckling branch point) ahead on the commanded path, warned of before the actuator
gets there.  A module's command given at rest: its exact operation range, at once.
Otherwise the commanded path is tracked ahead in the calls' leftover time
(:mod:`.simulation.path_ahead`) -- from the rest state, or, for a command given while the rods
move, from the quasi-static equilibrium at the actuator lengths then on the branch the rods are
on -- and its first jump is warned of if the actuator has not reached it yet.  The path
tracked from the rest state is also the quasi-static prediction when the rods come to rest.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import functools
import math
import time

import numpy as np

from . import events as ev
from .events import Outcome
from .mechanisms import head_of, stack_module_nodes
from .path_ahead import on_its_own_thread, PathAhead
from .simulator import DEFAULT_TIME_BUDGET, DEFAULT_WORK_LIMIT, Simulator, SOLVER_ERRORS
from ..dynamics.moving_module import MovingModule
from ..dynamics.moving_neck import MovingNeck
from ..dynamics.transient import SAME_LANDING, wrap
from ..neck.stack import Stack
from ..numerics.bounded_work import Job
from ..numerics.tolerances import DEFINITENESS_TOL

#: Pivot damping (N m s/rad) when none is given.
DEFAULT_DAMPING = 0.01


@dataclass(frozen=True)
class LiveState:
    """A module as it is now: actuator length and speed, angles, angular rates, and the
    actuator force (N, the rods' inertia included)."""

    rho: float
    rho_dot: float
    theta1: float
    theta2: float
    theta1_dot: float
    theta2_dot: float
    actuator_force: float


def _per_module(value):
    """A one-module motion's float, or a neck's tuple, as a tuple of floats."""
    return tuple(float(v) for v in np.atleast_1d(value))


class _Arrival:
    """Rods that came to rest, being verified (settled where they rest) and compared with
    the quasi-static prediction, each a Job run in the calls' time budgets."""

    __slots__ = ('start', 'start_state', 'end', 'reporting', 'cause', 'trigger', 'settling',
                 'predicting')

    def __init__(self, start, start_state, end, reporting, cause, trigger, settling,
                 predicting):
        self.start, self.start_state, self.end = start, start_state, end
        self.cause, self.trigger = cause, trigger
        self.reporting, self.settling, self.predicting = reporting, settling, predicting

    def jobs(self):
        return self.reporting, self.settling, self.predicting


class DynamicSimulator(Simulator):
    """A module or a neck (rod masses m1, m2 > 0 in every module), pivot ``damping``
    (one value per module, N m s/rad) and actuator speed limits max_rho_rate > 0;
    ``time_budget``, ``work_limit`` and ``clock`` as :class:`~.simulation.simulator.Simulator`'s.

    Raises ValueError (InvalidParameterError) for missing masses, a speed limit of 0 or a
    bad damping.
    """

    def __init__(self, modules, initial_theta, limits=None, names=None,
                 damping=(DEFAULT_DAMPING,), *, time_budget=DEFAULT_TIME_BUDGET,
                 work_limit=DEFAULT_WORK_LIMIT, clock=time.perf_counter):
        modules = tuple(modules)
        damping = tuple(damping)
        if len(damping) != len(modules):
            raise ValueError(f'{len(damping)} damping values for {len(modules)} modules')
        for value in damping:
            if _damping_problem(value):
                raise ValueError(_damping_problem(value))
        self._damping = tuple(float(d) for d in damping)
        self._epoch_ns = None
        self._cause = ''
        self._trigger = 0               # the module whose command started the motion
        self._moving = None
        self._in_motion = False         # the moving mechanism left its last verified rest
        self._forecast = None           # a PathAhead, or None
        self._arrival = None            # an _Arrival, or None
        self._after_reset = []          # calls made while a reset settles, replayed after
        #: Seconds the live state is behind the last call's time (0: caught up).
        self.lag = 0.0
        #: Calls that ended behind their time (the simulation could not keep up).
        self.lagging_calls = 0
        super().__init__(modules, initial_theta, limits, names, time_budget=time_budget,
                         work_limit=work_limit, clock=clock)

    # -- what it is now -------------------------------------------------------------------

    @property
    def moving(self):
        """True while the rods are not at rest at the actuators' targets (or their rest
        is still being verified)."""
        return self._moving.moving or self._arrival is not None

    @property
    def damping(self):
        """Pivot damping in use (N m s/rad; a neck: one per module)."""
        return self._moving.damping

    @property
    def stable(self):
        """False while the rods move: no verified equilibrium is claimed then."""
        return super().stable and not self.moving

    @property
    def state_time_ns(self):
        """The time (ns, of the calls' clock) the live state holds for: the last call's
        time, or earlier while the simulation lags; None before the first call."""
        if self._epoch_ns is None:
            return None
        return self._epoch_ns + int(round(self._moving.t * 1e9))

    def live(self, index):
        """The :class:`LiveState` now: the moving rods, or the verified rest state."""
        if not self.moving:
            params, eq = self.module(index)
            return LiveState(params.rho, 0.0, eq.theta1, eq.theta2, 0.0, 0.0,
                             float(eq.actuator_force))
        m = self._moving
        theta, rate = np.reshape(m.theta, (-1, 2))[index], np.reshape(m.theta_dot, (-1, 2))[index]
        return LiveState(_per_module(m.rho)[index], _per_module(m.rho_dot)[index],
                         float(theta[0]), float(theta[1]), float(rate[0]), float(rate[1]),
                         float(m.actuator_forces[index]))

    def design(self, index):
        """The design and loads of the moving rods now (the latest change, deferred ones
        included: they act on the rods at once)."""
        return self._latest_modules()[index]

    def module_nodes(self, index):
        """A1..A4 (4, 2) now: of the moving rods, or of the verified rest state."""
        if not self.moving:
            return super().module_nodes(index)
        return stack_module_nodes(self._moving.nodes, index)

    def head(self):
        """((x, y), angle) of the top chord A4 -> A3 now (moving or at rest)."""
        return head_of(self.module_nodes(len(self) - 1)) if self.moving else super().head()

    def target(self, index):
        return _per_module(self._moving.latest('target'))[index] if self.moving else None

    def status(self, index):
        """As :meth:`Simulator.status`; while the rods move, ``warn`` "in motion" with the
        figures of the last verified rest state."""
        status = super().status(index)
        if not self.moving:
            return status
        return dataclasses.replace(status, level='warn', message=(
            f'in motion toward rho={self.target(index):.6g} m: not a verified equilibrium; '
            f'figures of the last rest state at rho={status.params.rho:.6g} m'))

    def limits_refusal(self, index, rho_min, rho_max):
        refusal = super().limits_refusal(index, rho_min, rho_max)
        rho = _per_module(self._moving.rho)[index]
        target = _per_module(self._moving.latest('target'))[index]
        if not refusal and not (rho_min <= rho <= rho_max and rho_min <= target <= rho_max):
            refusal = (f'the moving actuator (rho={rho!r}, target {target!r}) is outside '
                       f'the requested [rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
        return refusal

    # -- commands ------------------------------------------------------------------------

    def command_rhos(self, targets, now_ns, cause='joint_commands'):
        """Actuator targets {module index: rho}: each actuator heads there at its
        max_rho_rate from where it is at ``now_ns`` (a neck's all arrive together), the
        rods keep their momentum.  Refused (nothing changes) as in the quasi-static mode."""
        if not targets:
            return Outcome()
        refusal = self.rhos_refusal(targets)
        if refusal is not None:
            return refusal
        if self.pending:                                   # a reset settles: after it
            return self._later(lambda now: self.command_rhos(targets, now, cause))
        self._start_call()
        at_rest = not self.moving
        warnings = self._jumps_ahead(targets, cause) if at_rest else ()
        full = list(_per_module(self._moving.latest('target')))
        for index, rho in targets.items():
            full[index] = float(rho)
        self._cause, self._trigger = cause, next(iter(targets))
        self._drop_forecast()
        t = self._seconds(now_ns)
        reports = self._moving.command(self._packed(full), t, self._deadline, self._clock)
        self._start_forecast(full, cause, moving=not at_rest)
        outcome = self._after_integration(reports, t, at_rest)
        return _with_events(outcome, warnings, first=True)

    def set_parameters(self, changes, now_ns, cause):
        """New design or loads: the rods move on from where they are under them."""
        if not changes:
            return Outcome()
        refusal = self.parameters_refusal(changes)
        if refusal is not None:
            return refusal
        modules = list(self._latest_modules())
        for index, fields in changes.items():
            modules[index] = modules[index].with_(**fields)
            if not (modules[index].m1 > 0.0 and modules[index].m2 > 0.0):
                return ev.refused(ev.PARAMETER_VALUE, (
                    f'dynamics mode needs rod masses m1, m2 > 0 (kg), got {self.names[index]} '
                    f'm1={modules[index].m1!r}, m2={modules[index].m2!r}'))
        if self.pending:
            return self._later(lambda now: self.set_parameters(changes, now, cause))
        self._start_call()
        at_rest = not self.moving
        self._cause, self._trigger = cause, next(iter(changes))
        self._drop_forecast()
        design = modules[0] if len(modules) == 1 else Stack(tuple(modules))
        t = self._seconds(now_ns)
        reports = self._moving.change(t, params=design, deadline=self._deadline,
                                      clock=self._clock)
        return self._after_integration(reports, t, at_rest)

    def set_limits(self, index, limits, now_ns):
        """As :meth:`Simulator.set_limits`; max_rho_rate must stay > 0 (the actuator's speed)."""
        if not limits.max_rho_rate > 0.0:
            return ev.refused(ev.PARAMETER_VALUE, f'dynamics mode needs max_rho_rate > 0 '
                                                  f'(the actuator speed), got '
                                                  f'{limits.max_rho_rate!r}')
        outcome = super().set_limits(index, limits, now_ns)
        if not outcome.accepted:
            return outcome
        rates = list(_per_module(self._moving.latest('max_rate')))
        rates[index] = limits.max_rho_rate
        t = self._seconds(now_ns)
        reports = self._moving.change(t, max_rate=self._packed(rates),
                                      deadline=self._deadline, clock=self._clock)
        return ev.combined([outcome, self._after_integration(reports, t, not self.moving)])

    def set_damping(self, index, damping, now_ns):
        """Pivot damping of one module (N m s/rad, > 0 and finite) from ``now_ns`` on."""
        if _damping_problem(damping):
            return ev.refused(ev.PARAMETER_VALUE, _damping_problem(damping))
        if self.pending:
            return self._later(lambda now: self.set_damping(index, damping, now))
        self._start_call()
        values = list(self._damping)
        values[index] = float(damping)
        self._damping = tuple(values)
        at_rest = not self.moving
        t = self._seconds(now_ns)
        reports = self._moving.change(t, damping=self._packed(values), deadline=self._deadline,
                                      clock=self._clock)
        return self._after_integration(reports, t, at_rest)

    def advance(self, now_ns):
        """Integrate the motion towards ``now_ns`` within the call's time budget; a snap
        that came to rest (and was verified) is a Jump.  A reset still settling goes on."""
        self._start_call()
        if self.pending:
            done = self._continue()
            if self.pending:
                return done
            later, self._after_reset = self._after_reset, []
            return ev.combined([done] + [call(now_ns) for call in later])
        t = self._seconds(now_ns)
        reports = self._moving.advance(t, self._deadline, self._clock)
        return self._after_integration(reports, t, False)

    def reset(self, modules, initial_theta):
        """As :meth:`Simulator.reset`; the rods start at rest in the reset state.  Calls
        made while a long settle goes on are applied once it ends."""
        for job in self._pending_jobs():
            job.cancel()
        self._forecast = self._arrival = None
        self._after_reset = []
        return super().reset(modules, initial_theta)

    # -- inside ---------------------------------------------------------------------------

    def _finish_reset(self, motion):
        """The settled start state, and the rods at rest in it."""
        outcome = super()._finish_reset(motion)
        if outcome.status == ev.OK:
            rates = [slot.limits.max_rho_rate for slot in self._slots]
            thetas = np.reshape(self.state.theta, (-1, 2))
            if len(self.modules) == 1:
                self._moving = MovingModule(self.modules[0], thetas[0], self._damping[0],
                                            rates[0])
            else:
                self._moving = MovingNeck(Stack(self.modules), thetas, self._damping, rates)
            self._moving.lazy_reports = True    # worked off in the calls' budgets
            self._epoch_ns, self._in_motion, self.lag = None, False, 0.0
        return outcome

    def _later(self, call):
        """Keep a call made while a reset settles; it is made when the reset is done."""
        self._after_reset.append(call)
        return Outcome()

    def _pending_jobs(self):
        if self._forecast is not None:
            yield self._forecast.job
        if self._arrival is not None:
            yield from self._arrival.jobs()

    def _packed(self, values):
        """Per-module values as the moving mechanism takes them (one module: a float)."""
        return values[0] if len(self) == 1 else tuple(values)

    def _latest_modules(self):
        """The moving mechanism's modules as the last change sets them (their rho is the
        simulator's business)."""
        params = self._moving.latest('params')
        return params.modules if isinstance(params, Stack) else (params,)

    def _seconds(self, now_ns):
        """Seconds since the first call (never going back: the moving mechanism's time)."""
        if self._epoch_ns is None:
            self._epoch_ns = now_ns - int(round(self._moving.t * 1e9))
        return max((now_ns - self._epoch_ns) * 1e-9, self._moving.t)

    def _after_integration(self, reports, t, was_at_rest):
        """After the moving mechanism was integrated towards ``t``: the lag, a rest to
        verify, and the jobs (forecast, verification) in the call's leftover time."""
        self.lag = max(t - self._moving.t, 0.0)
        if self.lag > 0.0:
            self.lagging_calls += 1
        if self._moving.moving:
            if not self._in_motion:
                self._in_motion = True
                self.revision += 1                # the status now says "in motion"
        elif self._in_motion:
            self._in_motion = False
            self._arrive(reports[-1] if reports else None)
        events = self._forecast_warnings()
        self._hint_rest()
        outcome = self._arrival_outcome()
        return _with_events(outcome, events, first=True)

    # -- the path ahead: early warning and prediction -------------------------------------

    def _start_forecast(self, targets, cause, moving=False):
        """Track the commanded path ahead (:mod:`.simulation.path_ahead`): from the rest state, or
        from where the moving rods are."""
        if not moving:
            self._forecast = PathAhead.from_rest(self._mechanism, self.modules, self.state,
                                                 targets, self._trigger, cause, self._clock)
            return
        m = self._moving
        self._forecast = PathAhead.from_motion(
            self._mechanism, m.params.modules if isinstance(m.params, Stack) else (m.params,),
            _per_module(m.rho), np.reshape(m.theta, (-1, 2)), targets, self._trigger, cause,
            self._clock)

    def _drop_forecast(self):
        """A new command or change: the path tracked ahead no longer holds."""
        if self._forecast is not None and (self._arrival is None or
                                           self._arrival.predicting is not self._forecast.job):
            self._forecast.job.cancel()
        self._forecast = None

    def _forecast_warnings(self):
        """Work on the forecast; once done, the early warning if its path jumps ahead of
        the actuator (a module's command at rest was warned of by its exact range)."""
        look = self._forecast
        if look is None or look.warned or not look.job.run(self._deadline):
            return ()
        look.warned = True
        if self._mechanism.has_operation_range and look.state is not None:
            return ()                   # (warned of by the exact range, at the command)
        warning = look.warning(_per_module(self._moving.rho)[look.index])
        return () if warning is None else (warning,)

    def _hint_rest(self):
        """Give the moving mechanism the forecast's landing as the likely rest state (if
        the rods come to rest there, no second settle is needed)."""
        look, m = self._forecast, self._moving
        if look is None or not look.job.done or m.rest_hint is not None or m.has_queued:
            return
        try:
            motion = look.job.result()
        except SOLVER_ERRORS:
            return
        end = tuple(p.with_(rho=r) for p, r in zip(self._latest_modules(),
                                                   _per_module(m.latest('target'))))
        if motion.status == 'ok' and tuple(motion.end) == end:
            m.rest_hint = motion.final

    # -- coming to rest ---------------------------------------------------------------------

    def _arrive(self, report):
        """The rods came to rest: the snap's figures (``report``, a function computing
        them, or None), the verification of the rest state and the prediction, in Jobs."""
        m = self._moving
        end = tuple(p.with_(rho=r) for p, r in zip(self._latest_modules(), _per_module(m.rho)))
        thetas = np.reshape(m.theta, (-1, 2)).copy()
        found = m.rest.eq if m.rest is not None else None      # settled where they rest
        settling = Job((lambda: found) if found is not None else functools.partial(
            self._mechanism.settle, end, thetas), self._clock)
        look = self._forecast
        if look is not None and look.start == self.modules and look.state is self.state \
                and look.end == end:
            predicting = look.job
        else:
            predicting = on_its_own_thread(Job(functools.partial(
                self._mechanism.track, self.modules, end, self.state), self._clock))
        creep = self._creep_report()
        reporting = Job(report if report is not None else (lambda: creep), self._clock)
        self._arrival = _Arrival(self.modules, self.state, end, reporting, self._cause,
                                 self._trigger, settling, predicting)

    def _arrival_outcome(self):
        """Work on the rest's verification and prediction; once both are done, the rest
        state becomes the verified state and a snap on the way is a Jump."""
        arrival = self._arrival
        if arrival is None or not all(job.run(self._deadline) for job in arrival.jobs()):
            return Outcome()
        self._arrival = None
        try:
            eq = arrival.settling.result()
        except SOLVER_ERRORS as exc:
            return self._failed(arrival.trigger,
                                f'{arrival.cause}: no equilibrium where the rods rest: {exc}')
        if not eq.eigenvalues[0] > DEFINITENESS_TOL * abs(eq.eigenvalues[-1]):
            return self._failed(arrival.trigger, f'{arrival.cause}: the rods rest on an '
                                                 f'unstable state')
        self._set_state(arrival.end, eq)
        for slot in self._slots:
            slot.tracking = 'ok'
        try:
            motion = arrival.predicting.result()
        except SOLVER_ERRORS:
            motion = None
        jump = self._snap_jump(arrival, eq, motion)
        return Outcome(events=(jump,)) if jump is not None else Outcome()

    def _creep_report(self):
        """The figures of a motion that never reached the onset speed (heavy damping can
        creep across a fold): no snap figures, only where the rods rest."""
        report = dict.fromkeys(('onset_rho', 'onset_time', 'peak_speed',
                                'peak_actuator_force', 'overshoot', 'settle_time'))
        report.update(settled=True, final=self._moving.final_state())
        return report

    def _snap_jump(self, arrival, eq, motion):
        """A Jump for a snap that came to rest, with the quasi-static prediction of the
        same change (``motion``, or None if the tracker failed) beside it; None if the rods
        only moved fast along their branch."""
        report = arrival.reporting.result()
        landing = np.reshape(np.asarray(eq.theta, dtype=float), (-1, 2))
        found = _critical_point(report, arrival, motion, landing)
        if found is None:
            return None
        (kind, s, critical, from_theta, _, ambiguous, _), predicted, elsewhere = found
        # (the rods rest in an equilibrium of the parameters now, not of the critical ones)
        jump = self._record_jump((kind, s, critical, from_theta, landing, ambiguous,
                                  tuple(self.modules)), arrival.trigger, arrival.cause)
        return dataclasses.replace(jump, dynamics=_figures(report, arrival.trigger, predicted,
                                                           elsewhere))


def _critical_point(report, arrival, motion, landing):
    """(the jump's critical point as the tracker's raw jump, the predicted landing or None,
    whether the rods landed elsewhere), or None if the motion was no jump: fast along its
    branch, or slow with no fold on the way.  With no fold on the quasi-static path but a
    landing elsewhere, inertia alone made the jump: ``inertial``, from the last rest state
    at the onset's actuator lengths."""
    predicted = raw = None
    if motion is not None:
        predicted = np.reshape(np.asarray(motion.final.theta, dtype=float), (-1, 2))
        raw = motion.jumps[0] if motion.jumps else None
    elsewhere = predicted is None or bool(
        np.max(np.abs(wrap(landing - predicted))) > SAME_LANDING)
    if raw is None and (not elsewhere or report['onset_rho'] is None):
        return None
    if raw is None:
        start = arrival.start
        onset_rhos = _per_module(report['onset_rho'])
        raw = ('inertial', 1.0, tuple(p.with_(rho=r) for p, r in zip(start, onset_rhos)),
               np.reshape(arrival.start_state.theta, (-1, 2)), None, False, None)
    return raw, predicted, elsewhere


def _with_events(outcome, events, first=False):
    """``outcome`` with ``events`` added (before its own: ``first``)."""
    if not events:
        return outcome
    events = tuple(events)
    both = events + outcome.events if first else outcome.events + events
    return Outcome(status=outcome.status, events=both, reason=outcome.reason,
                   message=outcome.message)


def _figures(report, index, predicted, elsewhere):
    """A jump's dynamic figures: the summary keys with ``onset_rho``, ``final`` and the
    quasi-static landing of the module that jumped; a neck adds every module's under
    ``modules`` (``onset_rho``, ``final_theta``, ``quasi_static_theta``)."""
    figures = dict(report)
    final = report['final']
    finals = np.reshape(final['theta'] if 'theta' in final else
                        [final['theta1'], final['theta2']], (-1, 2))
    onset_rhos = None if report['onset_rho'] is None else _per_module(report['onset_rho'])
    figures['onset_rho'] = None if onset_rhos is None else onset_rhos[index]
    figures['final'] = {'theta1': float(finals[index][0]), 'theta2': float(finals[index][1]),
                        'speed': float(final['speed'])}
    figures['quasi_static_final'] = (None if predicted is None else
                                     {'theta1': float(predicted[index][0]),
                                      'theta2': float(predicted[index][1])})
    figures['lands_elsewhere'] = elsewhere
    if len(finals) > 1:
        figures['modules'] = {
            'onset_rho': None if onset_rhos is None else list(onset_rhos),
            'final_theta': finals.tolist(),
            'quasi_static_theta': None if predicted is None else predicted.tolist()}
    return figures


def _damping_problem(damping):
    """Why ``damping`` is no pivot damping of the dynamics mode ('' if it is): without
    damping the rods never come to rest."""
    if isinstance(damping, (int, float)) and 0.0 < damping < math.inf:
        return ''
    return f'damping must be > 0 and finite (N m s/rad), got {damping!r}'
