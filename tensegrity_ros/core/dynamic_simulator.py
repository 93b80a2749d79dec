"""The simulator in dynamics mode (DESIGN.md section 9): the rods move in real time.

:class:`DynamicSimulator` has the :class:`~.simulator.Simulator` interface, but a
command does not jump the state to the end of a tracked path: the actuator runs at its
speed limit and the rods follow with their inertia (:class:`~.moving_module.MovingModule`),
integrated up to each call's time.  Commands, loads and parameter changes during a
transient act on the moving rods.  While the rods move the state is not a verified
equilibrium (``stable`` is False, ``status`` is ``warn`` "in motion"); when they come to
rest, the rest state is verified (settled, positive definite) and becomes the
simulator's state, and a snap on the way is a :class:`~.events.Jump` whose ``dynamics``
holds the figures (onset_rho, peak_speed, peak_actuator_force, overshoot, settle_time,
final) beside the quasi-static prediction.  One module only (a neck's live dynamics is
not built yet).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import events as ev
from .events import Outcome
from .mechanisms import head_of
from .module import node_positions
from .moving_module import MovingModule
from .simulator import DEFINITENESS_TOL, SOLVER_ERRORS, Simulator
from .transient import SAME_LANDING, wrap

#: Pivot damping (N m s/rad) when none is given.
DEFAULT_DAMPING = 0.01


@dataclass(frozen=True)
class LiveState:
    """A module as it is now: actuator length and speed, angles, angular rates, and the
    actuator force (N, rod 2's inertia included)."""

    rho: float
    rho_dot: float
    theta1: float
    theta2: float
    theta1_dot: float
    theta2_dot: float
    actuator_force: float


class DynamicSimulator(Simulator):
    """One module (``len(modules) == 1``) with rod masses m1, m2 > 0, pivot ``damping``
    (one value per module, N m s/rad) and an actuator speed limit max_rho_rate > 0.

    Raises ValueError (InvalidParameterError) for a neck, missing masses, a speed limit
    of 0 or a bad damping.
    """

    def __init__(self, modules, initial_theta, limits=None, names=None,
                 damping=(DEFAULT_DAMPING,)):
        modules = tuple(modules)
        if len(modules) != 1:
            raise ValueError(f'dynamics mode simulates one module, got {len(modules)} '
                             f'(the live dynamics of a neck is not built)')
        if _damping_problem(damping[0]):
            raise ValueError(_damping_problem(damping[0]))
        self._damping = float(damping[0])
        self._epoch_ns = None
        self._cause = ''
        super().__init__(modules, initial_theta, limits, names)

    # -- what it is now -------------------------------------------------------------------

    @property
    def moving(self):
        """True while the rods are not at rest at the actuator's target."""
        return self._moving.moving

    @property
    def damping(self):
        """Pivot damping in use (N m s/rad)."""
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
        theta, rate = m.theta, m.theta_dot
        return LiveState(m.rho, m.rho_dot, float(theta[0]), float(theta[1]),
                         float(rate[0]), float(rate[1]), m.actuator_force)

    def module_nodes(self, index):
        """A1..A4 (4, 2) now: of the moving rods, or of the verified rest state."""
        if not self.moving:
            return super().module_nodes(index)
        m = self._moving
        return node_positions(m.params.with_(rho=m.rho), m.theta)

    def head(self):
        """((x, y), angle) of the top chord A4 -> A3 now (moving or at rest)."""
        return head_of(self.module_nodes(0)) if self.moving else super().head()

    def target(self, index):
        return self._moving.target if self.moving else None

    def status(self, index):
        """As :meth:`Simulator.status`; while the rods move, ``warn`` "in motion" with the
        figures of the last verified rest state."""
        status = super().status(index)
        if not self.moving:
            return status
        return dataclasses.replace(status, level='warn', message=(
            f'in motion toward rho={self._moving.target:.6g} m: not a verified equilibrium; '
            f'figures of the last rest state at rho={status.params.rho:.6g} m'))

    def limits_refusal(self, index, rho_min, rho_max):
        refusal = super().limits_refusal(index, rho_min, rho_max)
        m = self._moving
        if not refusal and not (rho_min <= m.rho <= rho_max and rho_min <= m.target <= rho_max):
            refusal = (f'the moving actuator (rho={m.rho!r}, target {m.target!r}) is outside '
                       f'the requested [rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
        return refusal

    # -- commands ------------------------------------------------------------------------

    def command_rhos(self, targets, now_ns, cause='joint_commands'):
        """Actuator target: the actuator heads there at max_rho_rate from where it is now,
        the rods keep their momentum.  Refused (nothing changes) as in the quasi-static
        mode."""
        if not targets:
            return Outcome()
        refusal = self.rhos_refusal(targets)
        if refusal is not None:
            return refusal
        [(index, rho)] = targets.items()
        warning = self._jump_ahead(index, rho, cause)
        arrived = self._advance_to(self._seconds(now_ns))
        self._cause = cause
        self._moved(lambda t: self._moving.command(rho, t), now_ns)
        return _with_first(warning, arrived)

    def set_parameters(self, changes, now_ns, cause):
        """New design or loads: the rods move on from where they are under them."""
        if not changes:
            return Outcome()
        refusal = self.parameters_refusal(changes)
        if refusal is not None:
            return refusal
        [(index, fields)] = changes.items()
        end = self._moving.params.with_(**fields)
        if not (end.m1 > 0.0 and end.m2 > 0.0):
            return ev.refused(ev.PARAMETER_VALUE, f'dynamics mode needs rod masses m1, m2 > 0 '
                                                  f'(kg), got m1={end.m1!r}, m2={end.m2!r}')
        arrived = self._advance_to(self._seconds(now_ns))
        self._cause = cause
        self._moved(lambda t: self._moving.change(t, params=end), now_ns)
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
            self._moving.change(self._moving.t, max_rate=limits.max_rho_rate)
        return ev.combined([arrived, outcome]) if outcome.accepted else outcome

    def set_damping(self, index, damping, now_ns):
        """Pivot damping (N m s/rad, > 0 and finite) from ``now_ns`` on."""
        if _damping_problem(damping):
            return ev.refused(ev.PARAMETER_VALUE, _damping_problem(damping))
        arrived = self._advance_to(self._seconds(now_ns))
        self._moved(lambda t: self._moving.change(t, damping=float(damping)), now_ns)
        self._damping = float(damping)
        return arrived

    def advance(self, now_ns):
        """Integrate the motion up to ``now_ns``; a snap that came to rest is a Jump."""
        return self._advance_to(self._seconds(now_ns))

    def reset(self, modules, initial_theta):
        """As :meth:`Simulator.reset`; the rods start at rest in the reset state."""
        outcome = super().reset(modules, initial_theta)
        if outcome.accepted:
            self._moving = MovingModule(self.modules[0], self.state.theta, self._damping,
                                        self._slots[0].limits.max_rho_rate)
            self._epoch_ns = None
        return outcome

    # -- inside ---------------------------------------------------------------------------

    def _seconds(self, now_ns):
        """Seconds since the first call (never going back: the moving module's time)."""
        if self._epoch_ns is None:
            self._epoch_ns = now_ns - int(round(self._moving.t * 1e9))
        return max((now_ns - self._epoch_ns) * 1e-9, self._moving.t)

    def _moved(self, change, now_ns):
        """Apply a change to the moving module at ``now_ns``; a status change bumps the
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
        end = (m.params.with_(rho=m.rho),)
        try:
            eq = self._mechanism.settle(end, [m.theta])
        except SOLVER_ERRORS as exc:
            return self._failed(0, f'{self._cause}: no equilibrium where the rods rest: {exc}')
        if not eq.eigenvalues[0] > DEFINITENESS_TOL * abs(eq.eigenvalues[-1]):
            return self._failed(0, f'{self._cause}: the rods rest on an unstable state')
        start, start_state = self.modules, self.state
        self._set_state(end, eq)
        self._slots[0].tracking = 'ok'
        if report is None:
            return Outcome()
        jump = self._snap_jump(start, start_state, eq, report)
        return Outcome(events=(jump,)) if jump is not None else Outcome()

    def _snap_jump(self, start, start_state, eq, report):
        """A Jump for a snap that came to rest, with the quasi-static prediction of the
        same change beside it; None if the rods only moved fast along their branch."""
        try:
            motion = self._mechanism.track(start, self.modules, start_state)
            predicted = np.asarray(motion.final.theta, dtype=float)
            raw = motion.jumps[0] if motion.jumps else None
        except SOLVER_ERRORS:
            predicted, raw = None, None
        landing = np.asarray(eq.theta, dtype=float)
        elsewhere = predicted is None or bool(
            np.max(np.abs(wrap(landing - predicted))) > SAME_LANDING)
        if raw is None and not elsewhere:
            return None
        if raw is None:     # inertia alone: no fold on the quasi-static path
            raw = ('inertial', 1.0, (self.modules[0].with_(rho=report['onset_rho']),),
                   np.array([start_state.theta]), None, False)
        kind, s, critical, from_theta, _, ambiguous = raw
        figures = dict(report)
        figures['quasi_static_final'] = (None if predicted is None else
                                         {'theta1': float(predicted[0]),
                                          'theta2': float(predicted[1])})
        figures['lands_elsewhere'] = elsewhere
        jump = self._record_jump((kind, s, critical, from_theta, np.array([landing]), ambiguous),
                                 0, self._cause)
        return dataclasses.replace(jump, dynamics=figures)


def _damping_problem(damping):
    """Why ``damping`` is no pivot damping of the dynamics mode ('' if it is): without
    damping the rods never come to rest."""
    if isinstance(damping, (int, float)) and 0.0 < damping < math.inf:
        return ''
    return f'damping must be > 0 and finite (N m s/rad), got {damping!r}'


def _with_first(event, outcome):
    """``outcome`` with ``event`` (or nothing if None) before its events."""
    if event is None:
        return outcome
    return Outcome(status=outcome.status, events=(event,) + outcome.events)
