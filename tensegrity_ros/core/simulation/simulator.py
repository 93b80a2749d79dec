"""The mechanism as a user drives it: a neck of N modules (N = 1 included), ROS-free.

A :class:`Simulator` always holds a verified stable equilibrium.  Actuator targets
(with an optional speed limit per module), loads and parameter changes move the
parameters along straight paths that the tracker follows; :meth:`Simulator.advance`
moves speed-limited actuators on in time.  Every call returns an
:class:`~tensegrity_ros.core.simulation.events.Outcome`: ``ok``, ``failed`` (a path stopped early,
the state is the last verified one) or ``refused`` (bad input, nothing changed), with
the jumps, tracking failures and early warnings on the way.  Bad input a user could send
never raises; only programming errors (a wrong module index, a wrong type) do.

Bounded work: a call works at most ``time_budget`` seconds on tracking (then returns at
the tracker's next check point, see :mod:`.numerics.bounded_work`).  A path that needs longer
(a reset's settle too) goes on in the following calls (:meth:`Simulator.advance`, or
any command) exactly as an unbounded run would: the first call that defers it reports a
:class:`~tensegrity_ros.core.simulation.events.Deferred`, the state stays the last verified one
until the path ends, commands sent meanwhile are merged into one path that starts
where it ends (the latest value of every parameter wins), and speed-limited actuators
wait for the mechanism (they move on at their rate once it has followed).  A path that
has worked ``work_limit`` seconds in all is given up (a tracking failure, state kept).

One module and a neck share every line here: the solver behind (:mod:`.simulation.mechanisms`)
is the exact one-module tracker for N = 1 and the coupled stack tracker otherwise.
Times are integer nanoseconds (as ROS clocks give them), so elapsed times are exact.
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import math
import time

import numpy as np

from . import events as ev
from .events import Deferred, JumpAhead, Outcome, TrackingFailure
from .mechanisms import make_jump, mechanism_for
from .start_state import start_state
from ..continuation import TrackingError
from ..module.model import InvalidParameterError, ModuleParams
from ..module.supported_range import check_supported
from ..module.tracking import ModuleJump
from ..numerics.bounded_work import Job
from ..numerics.tolerances import verified_minimum

#: What a failing solver may raise on a bad path (anything else is a bug and propagates).
SOLVER_ERRORS = (TrackingError, ValueError, ArithmeticError, np.linalg.LinAlgError)
#: Seconds one call may spend tracking before it returns (the rest goes on in later
#: calls): well under the 100 ms a node's executor may stall on one input.
DEFAULT_TIME_BUDGET = 0.05
#: Seconds of tracking one path may use in all before it is given up (a guard: the
#: hardest in-range paths measured need ~1 s alone, ~7 s on a loaded machine; see
#: benchmarks/bench_worst_case.py).
DEFAULT_WORK_LIMIT = 60.0
#: Forces per loaded node: which ModuleParams fields a force at A3 / A4 sets.
FORCE_FIELDS = {'a3': ('f3x', 'f3y'), 'a4': ('f4x', 'f4y')}


@dataclass(frozen=True)
class ModuleLimits:
    """Per-module settings: accepted actuator targets, speed limit, warning threshold."""

    rho_min: float = 0.0
    rho_max: float = math.inf
    max_rho_rate: float = 0.0       # m/s; 0 = no limit (a command is one path)
    warn_margin: float = 0.05       # status 'warn' below this normalized margin


@dataclass(frozen=True)
class ModuleStatus:
    """Everything a status report of one module shows (see msg_docs/equilibrium.md).

    ``level`` is ``ok``, ``warn`` (near a jump, or tracking stopped early) or ``error``
    (not a stable equilibrium: never expected).
    """

    level: str
    message: str
    params: ModuleParams
    eq: object
    normalized: float
    num_equilibria: object
    num_stable: object
    operation_range: object
    last_jump: object
    jumps_total: int
    tracking: str
    warn_margin: float


def _limits_problem(limits):
    """Why ``limits`` are not usable limits ('' if they are)."""
    lo, hi, rate, warn = limits.rho_min, limits.rho_max, limits.max_rho_rate, limits.warn_margin
    if math.isnan(lo) or math.isnan(hi) or not lo <= hi:
        return f'rho_min={lo!r} and rho_max={hi!r} must be numbers with rho_min <= rho_max'
    if not (math.isfinite(rate) and rate >= 0.0):
        return f'max_rho_rate must be finite and >= 0, got {rate!r}'
    if not (math.isfinite(warn) and warn >= 0.0):
        return f'warn_margin must be finite and >= 0, got {warn!r}'
    return ''


class _Module:
    """Mutable per-module state of the simulator: settings, motion, jump record."""

    def __init__(self, limits):
        self.limits = limits
        self.target = None              # pending rho target of a speed-limited actuator
        self.cause = ''
        self.stamp_ns = 0               # time the actuator was last moved to
        self.last_jump = None
        self.tracking = 'ok'


class _Path:
    """A straight path to the modules ``end``, caused by ``cause`` of module ``trigger``
    (a plain class: one is made per command, on the small-step hot path)."""

    __slots__ = ('end', 'cause', 'trigger')

    def __init__(self, end, cause, trigger):
        self.end, self.cause, self.trigger = end, cause, trigger


class _Lookahead:
    """A speed-limited neck actuator's path to ``rho`` tracked ahead in a
    :class:`~.numerics.bounded_work.Job`, for an early warning (see
    :meth:`Simulator.command_rhos`)."""

    __slots__ = ('rho', 'cause', 'job')

    def __init__(self, rho, cause, job):
        self.rho, self.cause, self.job = rho, cause, job


class _Motion:
    """A path tracked in slices: its :class:`~.numerics.bounded_work.Job`, the work done."""

    __slots__ = ('path', 'job', 'finish', 'worked', 'deferred')

    def __init__(self, path, job, finish):
        self.path, self.job, self.finish = path, job, finish   # finish(motion) -> Outcome
        self.worked = 0.0           # seconds of tracking so far
        self.deferred = False       # a Deferred was reported


class Simulator:
    """A neck of ``len(modules)`` modules (bottom to top), started in the stable
    equilibrium whose basin holds ``initial_theta`` (one [t1, t2] per module).

    ``names`` label the modules in messages (default ``m0``, ``m1`` ...).  Raises
    ``ValueError`` for unusable limits or if there is no stable equilibrium to start from.
    ``time_budget`` (s, None: unbounded) bounds the tracking work of one call,
    ``work_limit`` (s) that of one path (see the module docstring); ``clock`` gives the
    time they are measured in (``time.perf_counter``; tests inject a counting clock).
    """

    def __init__(self, modules, initial_theta, limits=None, names=None, *,
                 time_budget=DEFAULT_TIME_BUDGET, work_limit=DEFAULT_WORK_LIMIT,
                 clock=time.perf_counter):
        modules = tuple(modules)
        if not modules:
            raise ValueError('a simulator needs at least one module')
        self.names = tuple(names) if names is not None else tuple(
            f'm{i}' for i in range(len(modules)))
        if len(self.names) != len(modules):
            raise ValueError(f'{len(self.names)} names for {len(modules)} modules')
        limits = list(limits) if limits is not None else [ModuleLimits()] * len(modules)
        if len(limits) != len(modules):
            raise ValueError(f'{len(limits)} limits for {len(modules)} modules')
        for name, lim in zip(self.names, limits):
            if _limits_problem(lim):
                raise ValueError(f'{name}: {_limits_problem(lim)}')
        self._mechanism = mechanism_for(len(modules))
        self._slots = [_Module(lim) for lim in limits]
        self.modules = None             # live ModuleParams, bottom to top
        self.state = None               # live verified equilibrium (N = 1: Equilibrium)
        self.jumps_total = 0
        self.revision = 0               # bumped whenever anything a status shows changes
        self.time_budget, self.work_limit, self._clock = time_budget, work_limit, clock
        self._deadline = math.inf       # of the running call
        self._motion = None             # the path being tracked (a _Motion), or None
        self._queued = None             # the _Path to track after it, or None
        self._lookaheads = {}           # module index -> _Lookahead (a neck's early warnings)
        self._look_later = set()        # modules to track ahead once no path is pending
        self.time_budget = None         # the start is settled in one call, however long
        started = self.reset(modules, initial_theta)
        self.time_budget = time_budget
        if not started.accepted:
            raise ValueError(started.message)

    # -- what it is now -----------------------------------------------------------------

    def __len__(self):
        return len(self._slots)

    def module(self, index):
        """(live ModuleParams, verified view with theta1, theta2, actuator_force ...)."""
        return self.modules[index], self._views[index]

    def target(self, index):
        """The pending target of a speed-limited actuator, or None when it is idle."""
        return self._slots[index].target

    def limits(self, index):
        return self._slots[index].limits

    @property
    def pending(self):
        """True while a path is being tracked over several calls (or waits for one)."""
        return self._motion is not None or self._queued is not None

    def goal(self, index):
        """The ModuleParams module ``index`` is heading to (the pending paths' end, else live)."""
        return self._goals()[index]
    design = goal       # the design and loads in effect now (DynamicSimulator: the rods')

    def module_nodes(self, index):
        """A1..A4 of a module, (4, 2), in the base frame of the bottom module."""
        return self._mechanism.module_nodes(self.modules, self.state, index)

    def head(self):
        """((x, y), angle): midpoint and direction of the top chord A4 -> A3."""
        return self._mechanism.head(self.modules, self.state)

    @property
    def stable(self):
        return bool(self.state.stable)

    def status(self, index):
        """The :class:`ModuleStatus` of one module (exact counts and range for N = 1)."""
        params, eq = self.module(index)
        slot = self._slots[index]
        normalized = self._mechanism.normalized_margin(self.modules, self.state)
        num, num_stable = self._mechanism.counts(self.modules)
        level, message = self._level(slot, eq, normalized)
        return ModuleStatus(
            level=level, message=message, params=params, eq=eq, normalized=normalized,
            num_equilibria=num, num_stable=num_stable,
            operation_range=self._mechanism.operation_range(self.modules, self.state),
            last_jump=slot.last_jump, jumps_total=self.jumps_total, tracking=slot.tracking,
            warn_margin=slot.limits.warn_margin)

    def _level(self, slot, eq, normalized):
        if not eq.stable:
            return 'error', 'not a stable equilibrium'
        if slot.tracking != 'ok':
            return 'warn', f'tracking stopped early: {slot.tracking}'
        if normalized < slot.limits.warn_margin:
            return 'warn', (f'stable, near a jump: stability margin {eq.stability_margin:.4g} '
                            f'{self._mechanism.margin_unit} (normalized {normalized:.3g} '
                            f'< warn_margin {slot.limits.warn_margin:g})')
        return 'ok', f'stable, stability margin {eq.stability_margin:.4g}'

    def limits_refusal(self, index, rho_min, rho_max):
        """Why [rho_min, rho_max] cannot be the module's limits now ('' if it can): the
        actuator and its pending target must stay inside."""
        rho, target = self.goal(index).rho, self._slots[index].target
        if not rho_min <= rho <= rho_max:
            return (f'the actuator is at rho={rho!r}, outside the requested '
                    f'[rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
        if target is not None and not rho_min <= target <= rho_max:
            return (f'the pending target rho={target!r} is outside the requested '
                    f'[rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
        return ''

    # -- commands -----------------------------------------------------------------------

    def command_rho(self, index, rho, now_ns, cause='rho_cmd'):
        """Actuator target of one module (see :meth:`command_rhos`)."""
        return self.command_rhos({index: rho}, now_ns, cause)

    def command_rhos(self, targets, now_ns, cause='joint_commands'):
        """Actuator targets {module index: rho}, all received at ``now_ns``.

        Refused as a whole if any target is not finite or outside its module's limits.
        Without speed limits every target is one straight path (all modules together);
        a speed-limited module moves toward its target in :meth:`advance`.

        Early warnings (:class:`JumpAhead`): one module's come from its exact operation
        range, for every command.  A neck has none; for a speed-limited actuator its
        path is tracked ahead instead (the other modules held where they are), in
        slices of this and the following calls' leftover time, and a jump on it is
        warned about unless the actuator has reached it by then (a load or design
        change tracks the paths ahead again).  A neck command without a speed limit is
        applied in the same call: its jump is reported, not announced (tracking it
        twice would double the cost of every command).
        """
        if not targets:
            return Outcome()
        refusal = self.rhos_refusal(targets)
        if refusal is not None:
            return refusal
        self._start_call()
        warnings = self._jumps_ahead(targets, cause)
        slots = self._slots
        if not any(slots[i].limits.max_rho_rate > 0.0 for i in targets):
            goals = self._goals()
            ends = {}
            for index, rho in targets.items():
                slots[index].target = None
                ends[index] = goals[index].with_rho(rho)
            moved = self._move(ends, cause, next(iter(targets)))
        else:
            moved = ev.combined(self._retarget(i, rho, now_ns, cause)
                                for i, rho in targets.items())
            moved = _with_warnings(moved, self._look_ahead(targets), after=True)
        return _with_warnings(moved, warnings)

    def set_force(self, index, node, force, now_ns, cause=None):
        """Force (fx, fy) at node ``'a3'`` or ``'a4'`` of a module (N, base frame)."""
        refusal = self.force_refusal(index, node, force)
        if refusal is not None:
            return refusal
        changes = dict(zip(FORCE_FIELDS[node], (float(v) for v in force)))
        return self.set_parameters({index: changes}, now_ns, cause or f'force_{node}')

    def rhos_refusal(self, targets):
        """What :meth:`command_rhos` would refuse in ``targets`` {index: rho} (a refused
        :class:`Outcome`), or None; changes nothing."""
        slots = self._slots
        for index, rho in targets.items():
            limits = slots[index].limits
            if not (math.isfinite(rho) and limits.rho_min <= rho <= limits.rho_max):
                return self._rho_refusal(index, rho)     # (the reason and its message)
        return None

    def force_refusal(self, index, node, force):
        """What :meth:`set_force` would refuse (not finite, beyond the supported
        magnitudes), or None; changes nothing."""
        fx, fy = (float(v) for v in force)
        if not (math.isfinite(fx) and math.isfinite(fy)):
            return ev.refused(ev.NON_FINITE, f'({fx!r}, {fy!r}) is not finite')
        try:
            check_supported(self.goal(index).with_(**dict(zip(FORCE_FIELDS[node], (fx, fy)))))
        except InvalidParameterError as exc:        # beyond the supported magnitudes or groups
            return ev.refused(ev.OUT_OF_RANGE, str(exc))
        return None

    def set_parameters(self, changes, now_ns, cause):
        """Change module parameters {module index: {field: value}} (any
        :class:`ModuleParams` field but rho): every change is one straight path, the
        jumps it causes are attributed to the first module named.  Pending speed-limited
        motion of those modules is first advanced to ``now_ns``."""
        if not changes:
            return Outcome()
        refusal = self.parameters_refusal(changes)
        if refusal is not None:
            return refusal
        self._start_call()
        self._drop_lookaheads()
        advanced = [self._advance_module(i, now_ns) for i in changes]
        ends = {i: self.goal(i).with_(**fields) for i, fields in changes.items()}
        moved = ev.combined(advanced + [self._move(ends, cause, next(iter(changes)))])
        heading = [i for i, slot in enumerate(self._slots) if slot.target is not None]
        return _with_warnings(moved, self._look_ahead(heading), after=True) if heading else moved

    def parameters_refusal(self, changes):
        """What :meth:`set_parameters` would refuse in ``changes`` (a refused
        :class:`Outcome`), or None; changes nothing."""
        try:
            for index, fields in changes.items():
                if 'rho' in fields:
                    raise InvalidParameterError('rho is commanded, not set: use command_rho')
                self.goal(index).with_(**fields)
        except (InvalidParameterError, TypeError) as exc:
            return ev.refused(ev.PARAMETER_VALUE, str(exc))
        return None

    def set_limits(self, index, limits, now_ns):
        """New :class:`ModuleLimits` of a module (pending motion is first advanced to
        ``now_ns`` under the old ones); refused if the actuator or its target would lie
        outside."""
        reason = _limits_problem(limits) or self.limits_refusal(index, limits.rho_min,
                                                                limits.rho_max)
        if reason:
            return ev.refused(ev.PARAMETER_VALUE, reason)
        self._start_call()
        self._drop_lookaheads()
        advanced = self._advance_module(index, now_ns)
        self._slots[index].limits = limits
        self.revision += 1
        return advanced

    def advance(self, now_ns):
        """Go on with a pending path (speed-limited actuators wait for it, this call
        included), else move every speed-limited actuator toward its target, up to time
        ``now_ns``."""
        self._start_call()
        if self.pending:
            for slot in self._slots:
                slot.stamp_ns = max(slot.stamp_ns, now_ns)
            return self._continue()
        moved = ev.combined([self._advance_module(i, now_ns)
                             for i, slot in enumerate(self._slots) if slot.target is not None])
        later, self._look_later = self._look_later, set()
        warnings = self._look_ahead(later) if later else self._lookahead_warnings()
        return _with_warnings(moved, warnings, after=True)

    def reset(self, modules, initial_theta):
        """Start over: settle ``modules`` from ``initial_theta`` (one [t1, t2] per module;
        None: the default start, see :func:`.simulation.start_state.start_state`); motion, jumps
        and tracking status are cleared.  Refused (state unchanged) if no stable equilibrium
        is reached.  A settle that needs more than the call's time budget (a loaded neck
        can take seconds) goes on in the following calls like a path (a Deferred; the old
        state until it ends); a settle that then fails is a TrackingFailure of the reset."""
        modules = tuple(modules)
        if len(modules) != len(self._slots):
            raise ValueError(f'{len(modules)} modules given, the simulator has '
                             f'{len(self._slots)}')
        if self._motion is not None:
            self._motion.job.cancel()
        self._motion = self._queued = None
        self._drop_lookaheads()
        for slot in self._slots:
            slot.target = None
        self._start_call()
        self._motion = _Motion(_Path(modules, 'reset', 0), Job(
            functools.partial(start_state, modules, initial_theta), self._clock),
            self._finish_reset)
        return self._work_on(self._motion)

    def _finish_reset(self, motion):
        """Apply a finished settle: the new start state, or a refusal (a failure if the
        reset was deferred: its call has long returned)."""
        try:
            state = motion.job.result()
        except SOLVER_ERRORS as exc:
            text = f'no stable equilibrium from initial_theta: {exc}'
            if motion.deferred:
                return self._failed(0, f'reset: {text}')
            return ev.refused(ev.PARAMETER_VALUE, text)
        self._set_state(motion.path.end, state)
        self.jumps_total = 0
        for slot in self._slots:
            slot.last_jump, slot.tracking = None, 'ok'
        return Outcome()

    # -- inside ---------------------------------------------------------------------------

    def _rho_refusal(self, index, rho):
        limits = self._slots[index].limits
        if not math.isfinite(rho):
            return ev.refused(ev.NON_FINITE, f'{rho!r} is not finite')
        if not limits.rho_min <= rho <= limits.rho_max:
            return ev.refused(ev.OUT_OF_RANGE, f'{rho!r} outside [rho_min, rho_max] = '
                                               f'[{limits.rho_min}, {limits.rho_max}]')
        return None

    def _jumps_ahead(self, targets, cause):
        """The :class:`JumpAhead` warnings of actuator ``targets`` {index: rho} (a tuple)."""
        if not self._mechanism.has_operation_range:
            return ()
        return tuple(w for w in (self._jump_ahead(i, rho, cause) for i, rho in targets.items())
                     if w is not None)

    def _jump_ahead(self, index, rho, cause):
        """A :class:`JumpAhead` if ``rho`` lies beyond an end of the live branch's
        operation range where the tracker jumps (a fold, or a branch point where the
        branch buckles: see :meth:`.OperationRange.jumps_at`).  One module only (the
        exact range); none while a path is pending (the live branch is not where the
        command starts)."""
        if self.pending:
            return None
        found = self._mechanism.operation_range(self.modules, self.state)
        if found is None:
            return None
        end = found.lower if rho < found.lower.rho else (
            found.upper if rho > found.upper.rho else None)
        if end is None or not found.jumps_at(end):
            return None
        return JumpAhead(module=index, rho=rho, end=end, cause=cause)

    def _look_ahead(self, indices):
        """Track ahead the path of each speed-limited neck actuator of ``indices`` that
        has a target (its earlier lookahead dropped); the warnings of those done within
        this call.  While a path is pending (the live state is not where the actuator
        is) they start in the first :meth:`advance` after it."""
        if self._mechanism.has_operation_range:
            return ()
        for index in indices:
            self._drop_lookaheads(index)
            slot = self._slots[index]
            if slot.target is None or slot.limits.max_rho_rate <= 0.0:
                continue
            if self.pending:
                self._look_later.add(index)
                continue
            work = functools.partial(self._mechanism.ahead, self.modules, self.state, index,
                                     slot.target)
            self._lookaheads[index] = _Lookahead(slot.target, slot.cause, Job(work, self._clock))
        return self._lookahead_warnings()

    def _lookahead_warnings(self):
        """Work on the lookaheads until the call's deadline (each makes progress); a
        :class:`JumpAhead` for each that ended on a jump its actuator is still heading
        for (one it has reached or passed meanwhile was reported as it happened)."""
        warnings = []
        for index, look in list(self._lookaheads.items()):
            if not look.job.run(self._deadline):
                continue
            del self._lookaheads[index]
            try:
                end = look.job.result()
            except SOLVER_ERRORS:           # the real path will meet and report it
                continue
            rho, target = self.goal(index).rho, self._slots[index].target
            if end is not None and target == look.rho and (end.rho - rho) * (target - rho) > 0:
                warnings.append(JumpAhead(module=index, rho=look.rho, end=end, cause=look.cause))
        return tuple(warnings)

    def _drop_lookaheads(self, index=None):
        """Stop tracking ahead for module ``index`` (all: None): its path changed."""
        if index is None:
            self._look_later.clear()
        self._look_later.discard(index)
        for i in ([index] if index is not None else list(self._lookaheads)):
            look = self._lookaheads.pop(i, None)
            if look is not None:
                look.job.cancel()

    def _retarget(self, index, rho, now_ns, cause):
        """A speed-limited actuator: advance to now, then head for the new target (an
        unlimited one goes there at once)."""
        slot = self._slots[index]
        if slot.limits.max_rho_rate <= 0.0:
            slot.target = None
            return self._move({index: self.goal(index).with_rho(rho)}, cause, index)
        advanced = self._advance_module(index, now_ns)
        slot.target = None if rho == self.goal(index).rho else rho
        slot.cause = cause
        slot.stamp_ns = now_ns
        return advanced

    def _advance_module(self, index, now_ns):
        """Move one actuator toward its target by max_rho_rate * elapsed time.  While a
        path is pending the actuator waits for the mechanism (no motion accrues, so the
        published actuator lengths keep to the speed limit: no catch-up step later)."""
        slot = self._slots[index]
        if slot.target is None:
            return Outcome()
        if self.pending:
            slot.stamp_ns = max(slot.stamp_ns, now_ns)
            return Outcome()
        dt = max(0, now_ns - slot.stamp_ns) * 1e-9
        rate, rho, target = slot.limits.max_rho_rate, self.goal(index).rho, slot.target
        if rate <= 0.0 or abs(target - rho) <= rate * dt:
            new_rho, slot.target = target, None
        elif dt <= 0.0:
            return Outcome()
        else:
            new_rho = rho + math.copysign(rate * dt, target - rho)
        slot.stamp_ns = now_ns
        moved = self._move({index: self.goal(index).with_rho(new_rho)}, slot.cause, index)
        if moved.status == ev.FAILED:
            slot.target = None
        if slot.target is None:         # there (or stopped): nothing ahead to warn of
            self._drop_lookaheads(index)
        return moved

    # -- paths, in slices of bounded work ---------------------------------------------------

    def _start_call(self):
        """The running call's deadline: its tracking stops at the first check point past it."""
        self._deadline = (math.inf if self.time_budget is None
                          else self._clock() + self.time_budget)

    def _goals(self):
        if self._queued is not None:
            return self._queued.end
        return self._motion.path.end if self._motion is not None else self.modules

    def _move(self, ends, cause, trigger):
        """Track the state to the goal modules with ``ends`` {index: ModuleParams} in
        place, on one straight path (after the pending one, merged with any that waits);
        a failure keeps the last verified state."""
        end = tuple(ends.get(i, m) for i, m in enumerate(self._goals()))
        if self._motion is None and end == self.modules:
            self._queued = None
            return Outcome()
        self._queued = _Path(end, cause, trigger)
        return self._continue()

    def _continue(self):
        """Track the pending path, then the one waiting, until done or out of time."""
        outcomes = []
        while self._motion is not None or self._queued is not None:
            if self._motion is None:
                if outcomes and self._clock() > self._deadline:
                    break
                path, self._queued = self._queued, None
                if path.end == self.modules:
                    continue
                self._motion = _Motion(path, Job(functools.partial(
                    self._mechanism.track, self.modules, path.end, self.state), self._clock),
                    self._finish)
            outcome = self._work_on(self._motion)
            if outcome is None:
                break
            outcomes.append(outcome)
        return ev.combined(outcomes)

    def _work_on(self, motion):
        """Resume ``motion`` until the deadline: its outcome once it ends (or is given up
        or first deferred: a Deferred), else None."""
        began = self._clock()
        if motion.job.run(self._deadline):
            self._motion = None
            return motion.finish(motion)
        motion.worked += self._clock() - began
        path = motion.path
        if self.work_limit is not None and motion.worked > self.work_limit:
            motion.job.cancel()
            self._motion = None
            return self._failed(path.trigger, f'{path.cause}: gave up after '
                                              f'{motion.worked:.3g} s of tracking')
        if motion.deferred:
            return None
        motion.deferred = True
        return Outcome(events=(Deferred(module=path.trigger, cause=path.cause, text=(
            f'tracking needs more than the time budget of {self.time_budget:g} s per '
            f'call; it goes on in the next calls'),),))

    def _finish(self, finished):
        """Apply a tracked path's result: the state it reached, its jumps, its status."""
        cause, trigger = finished.path.cause, finished.path.trigger
        try:
            motion = finished.job.result()
        except SOLVER_ERRORS as exc:
            return self._failed(trigger, f'{cause}: {exc}')
        eigenvalues = motion.final.eigenvalues
        if not verified_minimum(eigenvalues, motion.certificate):
            return self._failed(trigger, f'{cause}: tracker returned an unstable state')
        self._set_state(motion.end, motion.final)
        # passages first (a module's passage carries no s to order it by), then the jumps
        events = ev.passage_events(motion, trigger, cause)
        events += tuple(self._record_jump(raw, trigger, cause) for raw in motion.jumps)
        if motion.status != 'ok':
            failed = self._failed(trigger, f'{cause}: stopped at {self.names[trigger]} '
                                           f'rho={self.modules[trigger].rho!r}: '
                                           f'{motion.message}')
            return Outcome(status=ev.FAILED, events=events + failed.events)
        for slot in self._slots:
            slot.tracking = 'ok'
        return Outcome(events=events)

    def _failed(self, index, text):
        self._slots[index].tracking = text
        self.revision += 1
        return Outcome(status=ev.FAILED, events=(TrackingFailure(module=index, text=text),))

    def _record_jump(self, raw, trigger, cause):
        """Count a jump; every module records it (a neck jumps as a whole)."""
        self.jumps_total += 1
        jump = make_jump(raw, module=trigger, cause=cause, count=self.jumps_total)
        for i, slot in enumerate(self._slots):
            slot.last_jump = ModuleJump(kind=jump.kind, s=jump.s, params=jump.modules[i],
                                        from_theta=jump.from_theta[i],
                                        to_theta=jump.to_theta[i], ambiguous=jump.ambiguous)
        return jump

    def _set_state(self, modules, state):
        self.modules, self.state = tuple(modules), state
        self._views = self._mechanism.views(self.modules, state)
        self.revision += 1


def _with_warnings(outcome, warnings, after=False):
    """``outcome`` with early ``warnings`` before its events (after them: ``after``)."""
    if not warnings:
        return outcome
    events = outcome.events + warnings if after else warnings + outcome.events
    return Outcome(status=outcome.status, events=events, reason=outcome.reason,
                   message=outcome.message)
