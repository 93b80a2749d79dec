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

import functools
import math
import time

from . import events as ev
from .events import JumpAhead, Outcome
from .mechanisms import mechanism_for
from .module_limits import limits_problem, ModuleLimits, outside_new_limits, rho_refusal
from .module_status import ModuleStatus, status_level
from .tracked_state import SOLVER_ERRORS, TrackedState
from ..module.model import InvalidParameterError
from ..module.supported_range import check_supported
from ..numerics.bounded_work import Job

#: Seconds one call may spend tracking before it returns (the rest goes on in later
#: calls): well under the 100 ms a node's executor may stall on one input.
DEFAULT_TIME_BUDGET = 0.05
#: Seconds of tracking one path may use in all before it is given up (a guard: the
#: hardest in-range paths measured need ~1 s alone, ~7 s on a loaded machine; see
#: benchmarks/bench_worst_case.py).
DEFAULT_WORK_LIMIT = 60.0
#: Forces per loaded node: which ModuleParams fields a force at A3 / A4 sets.
FORCE_FIELDS = {'a3': ('f3x', 'f3y'), 'a4': ('f4x', 'f4y')}


class _Module:
    """Mutable per-module state of the simulator: settings, motion, jump record."""

    def __init__(self, limits):
        self.limits = limits
        self.target = None              # pending rho target of a speed-limited actuator
        self.cause = ''
        self.stamp_ns = 0               # time the actuator was last moved to
        self.last_jump = None
        self.tracking = 'ok'


class _Lookahead:
    """A speed-limited neck actuator's path to ``rho`` tracked ahead in a
    :class:`~.numerics.bounded_work.Job`, for an early warning (see
    :meth:`Simulator.command_rhos`)."""

    __slots__ = ('rho', 'cause', 'job')

    def __init__(self, rho, cause, job):
        self.rho, self.cause, self.job = rho, cause, job


class Simulator(TrackedState):
    """A neck of ``len(modules)`` modules (bottom to top), started in the stable
    equilibrium whose basin holds ``initial_theta`` (one [t1, t2] per module).

    ``names`` label the modules in messages (default ``m0``, ``m1`` ...).  Raises
    ``ValueError`` for unusable limits or if there is no stable equilibrium to start from.
    ``time_budget`` (s, None: unbounded) bounds the tracking work of one call,
    ``work_limit`` (s) that of one path (see the module docstring); ``clock`` gives the
    time they are measured in (``time.perf_counter``; tests inject a counting clock).
    The state, its queries and the paths' tracking are
    :class:`~.simulation.tracked_state.TrackedState`'s.
    """

    def __init__(self, modules, initial_theta, limits=None, names=None, *,
                 time_budget=DEFAULT_TIME_BUDGET, work_limit=DEFAULT_WORK_LIMIT,
                 clock=time.perf_counter):
        modules = tuple(modules)
        if not modules:
            raise ValueError('a simulator needs at least one module')
        names = tuple(names) if names is not None else tuple(
            f'm{i}' for i in range(len(modules)))
        if len(names) != len(modules):
            raise ValueError(f'{len(names)} names for {len(modules)} modules')
        limits = list(limits) if limits is not None else [ModuleLimits()] * len(modules)
        if len(limits) != len(modules):
            raise ValueError(f'{len(limits)} limits for {len(modules)} modules')
        for name, lim in zip(names, limits):
            if limits_problem(lim):
                raise ValueError(f'{name}: {limits_problem(lim)}')
        super().__init__(mechanism_for(len(modules)), [_Module(lim) for lim in limits], names,
                         time_budget, work_limit, clock)
        self._lookaheads = {}           # module index -> _Lookahead (a neck's early warnings)
        self._look_later = set()        # modules to track ahead once no path is pending
        self.time_budget = None         # the start is settled in one call, however long
        started = self.reset(modules, initial_theta)
        self.time_budget = time_budget
        if not started.accepted:
            raise ValueError(started.message)

    # -- what it is now -----------------------------------------------------------------

    def target(self, index):
        """The pending target of a speed-limited actuator, or None when it is idle."""
        return self._slots[index].target

    def limits(self, index):
        return self._slots[index].limits

    def goal(self, index):
        """The ModuleParams module ``index`` is heading to (the pending paths' end, else live)."""
        return self._goals()[index]
    design = goal       # the design and loads in effect now (DynamicSimulator: the rods')

    def status(self, index):
        """The :class:`ModuleStatus` of one module (exact counts and range for N = 1)."""
        params, eq = self.module(index)
        slot = self._slots[index]
        normalized = self._mechanism.normalized_margin(self.modules, self.state)
        num, num_stable = self._mechanism.counts(self.modules)
        level, message = status_level(eq, slot.tracking, normalized, slot.limits.warn_margin,
                                      self._mechanism.margin_unit)
        return ModuleStatus(
            level=level, message=message, params=params, eq=eq, normalized=normalized,
            num_equilibria=num, num_stable=num_stable,
            operation_range=self._mechanism.operation_range(self.modules, self.state),
            last_jump=slot.last_jump, jumps_total=self.jumps_total, tracking=slot.tracking,
            warn_margin=slot.limits.warn_margin)

    def limits_refusal(self, index, rho_min, rho_max):
        """Why [rho_min, rho_max] cannot be the module's limits now ('' if it can): the
        actuator and its pending target must stay inside."""
        return outside_new_limits(self.goal(index).rho, self._slots[index].target,
                                  rho_min, rho_max)

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
                return rho_refusal(limits, rho)     # (the reason and its message)
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
        reason = limits_problem(limits) or self.limits_refusal(index, limits.rho_min,
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
        self._cancel_paths()
        self._drop_lookaheads()
        for slot in self._slots:
            slot.target = None
        return self._settle(modules, initial_theta)

    # -- inside ---------------------------------------------------------------------------

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


def _with_warnings(outcome, warnings, after=False):
    """``outcome`` with early ``warnings`` before its events (after them: ``after``)."""
    if not warnings:
        return outcome
    events = outcome.events + warnings if after else warnings + outcome.events
    return Outcome(status=outcome.status, events=events, reason=outcome.reason,
                   message=outcome.message)
