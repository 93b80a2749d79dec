"""The simulator in dynamics mode (docs/model.md section 5): the rods move in real time.

:class:`DynamicSimulator` has the :class:`~.simulator.Simulator` interface, but a
command does not jump the state to the end of a tracked path: the actuators run at
their speed limits and the rods follow with their inertia, integrated up to each call's
time (:class:`~.moving_module.MovingModule` for one module,
:class:`~.moving_neck.MovingNeck` for a neck: one loop, :class:`~.live_motion.LiveMotion`).
Commands, loads and parameter changes during a transient act on the moving rods.  While
the rods move the state is not a verified equilibrium (``stable`` is False, ``status`` is
``warn`` "in motion"); when they come to rest, the rest state is verified (settled,
positive definite) and becomes the simulator's state, and a snap on the way is a
:class:`~.events.Jump` whose ``dynamics`` holds the figures (onset_rho, peak_speed,
peak_actuator_force, overshoot, settle_time, final) beside the quasi-static prediction.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import events as ev
from .events import Outcome
from .mechanisms import head_of, stack_module_nodes
from .moving_module import MovingModule
from .moving_neck import MovingNeck
from .simulator import SOLVER_ERRORS, Simulator
from .tolerances import DEFINITENESS_TOL
from .stack import Stack
from .transient import SAME_LANDING, wrap

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


class DynamicSimulator(Simulator):
    """A module or a neck (rod masses m1, m2 > 0 in every module), pivot ``damping``
    (one value per module, N m s/rad) and actuator speed limits max_rho_rate > 0.

    Raises ValueError (InvalidParameterError) for missing masses, a speed limit of 0 or a
    bad damping.
    """

    def __init__(self, modules, initial_theta, limits=None, names=None,
                 damping=(DEFAULT_DAMPING,)):
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
        super().__init__(modules, initial_theta, limits, names)

    # -- what it is now -------------------------------------------------------------------

    @property
    def moving(self):
        """True while the rods are not at rest at the actuators' targets."""
        return self._moving.moving

    @property
    def damping(self):
        """Pivot damping in use (N m s/rad; a neck: one per module)."""
        return self._moving.damping

    @property
    def stable(self):
        """False while the rods move: no verified equilibrium is claimed then."""
        return super().stable and not self.moving

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
        """The design and loads of the moving rods now (a change acts on them at once)."""
        return self._moving_modules()[index]

    def module_nodes(self, index):
        """A1..A4 (4, 2) now: of the moving rods, or of the verified rest state."""
        if not self.moving:
            return super().module_nodes(index)
        return stack_module_nodes(self._moving.nodes, index)

    def head(self):
        """((x, y), angle) of the top chord A4 -> A3 now (moving or at rest)."""
        return head_of(self.module_nodes(len(self) - 1)) if self.moving else super().head()

    def target(self, index):
        return _per_module(self._moving.target)[index] if self.moving else None

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
        rho, target = _per_module(self._moving.rho)[index], _per_module(self._moving.target)[index]
        if not refusal and not (rho_min <= rho <= rho_max and rho_min <= target <= rho_max):
            refusal = (f'the moving actuator (rho={rho!r}, target {target!r}) is outside '
                       f'the requested [rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
        return refusal

    # -- commands ------------------------------------------------------------------------

    def command_rhos(self, targets, now_ns, cause='joint_commands'):
        """Actuator targets {module index: rho}: each actuator heads there at its
        max_rho_rate from where it is now (a neck's all arrive together), the rods keep
        their momentum.  Refused (nothing changes) as in the quasi-static mode."""
        if not targets:
            return Outcome()
        refusal = self.rhos_refusal(targets)
        if refusal is not None:
            return refusal
        warnings = self._jumps_ahead(targets, cause)
        arrived = self._advance_to(self._seconds(now_ns))
        full = list(_per_module(self._moving.target))
        for index, rho in targets.items():
            full[index] = float(rho)
        self._cause, self._trigger = cause, next(iter(targets))
        self._moved(lambda t: self._moving.command(self._packed(full), t), now_ns)
        return Outcome(status=arrived.status, events=warnings + arrived.events)

    def set_parameters(self, changes, now_ns, cause):
        """New design or loads: the rods move on from where they are under them."""
        if not changes:
            return Outcome()
        refusal = self.parameters_refusal(changes)
        if refusal is not None:
            return refusal
        modules = list(self._moving_modules())
        for index, fields in changes.items():
            modules[index] = modules[index].with_(**fields)
            if not (modules[index].m1 > 0.0 and modules[index].m2 > 0.0):
                return ev.refused(ev.PARAMETER_VALUE, (
                    f'dynamics mode needs rod masses m1, m2 > 0 (kg), got {self.names[index]} '
                    f'm1={modules[index].m1!r}, m2={modules[index].m2!r}'))
        arrived = self._advance_to(self._seconds(now_ns))
        self._cause, self._trigger = cause, next(iter(changes))
        design = modules[0] if len(modules) == 1 else Stack(tuple(modules))
        self._moved(lambda t: self._moving.change(t, params=design), now_ns)
        return arrived

    def set_limits(self, index, limits, now_ns):
        """As :meth:`Simulator.set_limits`; max_rho_rate must stay > 0 (the actuator's speed)."""
        if not limits.max_rho_rate > 0.0:
            return ev.refused(ev.PARAMETER_VALUE, f'dynamics mode needs max_rho_rate > 0 '
                                                  f'(the actuator speed), got '
                                                  f'{limits.max_rho_rate!r}')
        arrived = self._advance_to(self._seconds(now_ns))
        outcome = super().set_limits(index, limits, now_ns)
        if outcome.accepted:
            rates = list(_per_module(self._moving.max_rate))
            rates[index] = limits.max_rho_rate
            self._moving.change(self._moving.t, max_rate=self._packed(rates))
        return ev.combined([arrived, outcome]) if outcome.accepted else outcome

    def set_damping(self, index, damping, now_ns):
        """Pivot damping of one module (N m s/rad, > 0 and finite) from ``now_ns`` on."""
        if _damping_problem(damping):
            return ev.refused(ev.PARAMETER_VALUE, _damping_problem(damping))
        arrived = self._advance_to(self._seconds(now_ns))
        values = list(self._damping)
        values[index] = float(damping)
        self._moved(lambda t: self._moving.change(t, damping=self._packed(values)), now_ns)
        self._damping = tuple(values)
        return arrived

    def advance(self, now_ns):
        """Integrate the motion up to ``now_ns``; a snap that came to rest is a Jump."""
        return self._advance_to(self._seconds(now_ns))

    def reset(self, modules, initial_theta):
        """As :meth:`Simulator.reset`; the rods start at rest in the reset state."""
        outcome = super().reset(modules, initial_theta)
        if outcome.accepted:
            rates = [slot.limits.max_rho_rate for slot in self._slots]
            thetas = np.reshape(self.state.theta, (-1, 2))
            if len(self.modules) == 1:
                self._moving = MovingModule(self.modules[0], thetas[0], self._damping[0],
                                            rates[0])
            else:
                self._moving = MovingNeck(Stack(self.modules), thetas, self._damping, rates)
            self._epoch_ns = None
        return outcome

    # -- inside ---------------------------------------------------------------------------

    def _packed(self, values):
        """Per-module values as the moving mechanism takes them (one module: a float)."""
        return values[0] if len(self) == 1 else tuple(values)

    def _moving_modules(self):
        """The moving mechanism's modules (their rho is the simulator's business)."""
        params = self._moving.params
        return params.modules if isinstance(params, Stack) else (params,)

    def _seconds(self, now_ns):
        """Seconds since the first call (never going back: the moving mechanism's time)."""
        if self._epoch_ns is None:
            self._epoch_ns = now_ns - int(round(self._moving.t * 1e9))
        return max((now_ns - self._epoch_ns) * 1e-9, self._moving.t)

    def _moved(self, change, now_ns):
        """Apply a change to the moving mechanism at ``now_ns``; a status change bumps the
        revision."""
        was = self.moving
        change(self._seconds(now_ns))
        if self.moving != was:
            self.revision += 1

    def _advance_to(self, t):
        """Integrate to ``t``; if the rods came to rest, verify the rest state."""
        was = self.moving
        reports = self._moving.advance(t)
        if not was or self.moving:
            return Outcome()
        self.revision += 1
        return self._came_to_rest(reports[-1] if reports else None)

    def _came_to_rest(self, report):
        """The rest state becomes the verified state; a snap on the way is a Jump."""
        m = self._moving
        end = tuple(p.with_(rho=r) for p, r in zip(self._moving_modules(), _per_module(m.rho)))
        try:
            eq = self._mechanism.settle(end, np.reshape(m.theta, (-1, 2)))
        except SOLVER_ERRORS as exc:
            return self._failed(self._trigger,
                                f'{self._cause}: no equilibrium where the rods rest: {exc}')
        if not eq.eigenvalues[0] > DEFINITENESS_TOL * abs(eq.eigenvalues[-1]):
            return self._failed(self._trigger, f'{self._cause}: the rods rest on an unstable '
                                               f'state')
        start, start_state = self.modules, self.state
        self._set_state(end, eq)
        for slot in self._slots:
            slot.tracking = 'ok'
        jump = self._snap_jump(start, start_state, eq, report or self._creep_report())
        return Outcome(events=(jump,)) if jump is not None else Outcome()

    def _creep_report(self):
        """The figures of a motion that never reached the onset speed (heavy damping can
        creep across a fold): no snap figures, only where the rods rest."""
        report = dict.fromkeys(('onset_rho', 'onset_time', 'peak_speed',
                                'peak_actuator_force', 'overshoot', 'settle_time'))
        report.update(settled=True, final=self._moving.final_state())
        return report

    def _snap_jump(self, start, start_state, eq, report):
        """A Jump for a snap that came to rest, with the quasi-static prediction of the
        same change beside it; None if the rods only moved fast along their branch."""
        try:
            motion = self._mechanism.track(start, self.modules, start_state)
            predicted = np.reshape(np.asarray(motion.final.theta, dtype=float), (-1, 2))
            raw = motion.jumps[0] if motion.jumps else None
        except SOLVER_ERRORS:
            predicted, raw = None, None
        landing = np.reshape(np.asarray(eq.theta, dtype=float), (-1, 2))
        elsewhere = predicted is None or bool(
            np.max(np.abs(wrap(landing - predicted))) > SAME_LANDING)
        if raw is None and (not elsewhere or report['onset_rho'] is None):
            return None         # fast along its branch, or slow with no fold on the way
        onset_rhos = (_per_module(report['onset_rho']) if report['onset_rho'] is not None
                      else tuple(p.rho for p in start))
        if raw is None:     # inertia alone: no fold on the quasi-static path
            raw = ('inertial', 1.0, tuple(p.with_(rho=r) for p, r in zip(start, onset_rhos)),
                   np.reshape(start_state.theta, (-1, 2)), None, False, None)
        kind, s, critical, from_theta, _, ambiguous, _ = raw
        # (the rods rest in an equilibrium of the parameters now, not of the critical ones)
        jump = self._record_jump((kind, s, critical, from_theta, landing, ambiguous,
                                  tuple(self.modules)), self._trigger, self._cause)
        return dataclasses.replace(jump, dynamics=_figures(report, self._trigger, predicted,
                                                           elsewhere))


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
