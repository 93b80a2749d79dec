"""A simulator's verified state, and the straight paths that move it in bounded work.

:class:`TrackedState` holds the live modules and their verified equilibrium, the jump
record and the path being tracked: a path is a :class:`~.numerics.bounded_work.Job` resumed in
slices, each call working until its deadline (``time_budget`` after the call began);
a path that needs longer goes on in the following calls, the state staying the last
verified one until it ends, and paths asked for meanwhile merge into the one that waits.
A path that has worked ``work_limit`` seconds in all is given up.  The commands that
ask for paths are :class:`~.simulation.simulator.Simulator`'s.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from . import events as ev
from .events import Deferred, Outcome, TrackingFailure
from .mechanisms import make_jump
from .start_state import start_state
from ..continuation import TrackingError
from ..module.tracking import ModuleJump
from ..numerics.bounded_work import Job
from ..numerics.tolerances import verified_minimum

#: What a failing solver may raise on a bad path (anything else is a bug and propagates).
SOLVER_ERRORS = (TrackingError, ValueError, ArithmeticError, np.linalg.LinAlgError)


class _Path:
    """A straight path to the modules ``end``, caused by ``cause`` of module ``trigger``
    (a plain class: one is made per command, on the small-step hot path)."""

    __slots__ = ('end', 'cause', 'trigger')

    def __init__(self, end, cause, trigger):
        self.end, self.cause, self.trigger = end, cause, trigger


class _Motion:
    """A path being tracked in slices: its :class:`~.numerics.bounded_work.Job` and the work
    done."""

    __slots__ = ('path', 'job', 'finish', 'worked', 'deferred')

    def __init__(self, path, job, finish):
        self.path, self.job, self.finish = path, job, finish   # finish(motion) -> Outcome
        self.worked = 0.0           # seconds of tracking so far
        self.deferred = False       # a Deferred was reported


class TrackedState:
    """The verified state of the ``len(slots)`` modules a ``mechanism`` (see
    :func:`.simulation.mechanisms.mechanism_for`) tracks, labelled ``names``, and the paths that
    move it; ``slots`` are the modules' mutable records (their ``last_jump`` and
    ``tracking`` are kept here).  ``time_budget`` (s, None: unbounded) bounds the
    tracking work of one call, ``work_limit`` (s) that of one path, both measured on
    ``clock``.  The state is set by the first :meth:`_settle`.
    """

    def __init__(self, mechanism, slots, names, time_budget, work_limit, clock):
        self.names = names
        self._mechanism = mechanism
        self._slots = slots
        self.modules = None             # live ModuleParams, bottom to top
        self.state = None               # live verified equilibrium (N = 1: Equilibrium)
        self.jumps_total = 0
        self.revision = 0               # bumped whenever anything a status shows changes
        self.time_budget, self.work_limit, self._clock = time_budget, work_limit, clock
        self._deadline = math.inf       # of the running call
        self._motion = None             # the path being tracked (a _Motion), or None
        self._queued = None             # the _Path to track after it, or None

    # -- what it is now -----------------------------------------------------------------

    def __len__(self):
        return len(self._slots)

    def module(self, index):
        """(live ModuleParams, verified view with theta1, theta2, actuator_force ...)."""
        return self.modules[index], self._views[index]

    def module_nodes(self, index):
        """A1..A4 of a module, (4, 2), in the base frame of the bottom module."""
        return self._mechanism.module_nodes(self.modules, self.state, index)

    def head(self):
        """((x, y), angle): midpoint and direction of the top chord A4 -> A3."""
        return self._mechanism.head(self.modules, self.state)

    @property
    def stable(self):
        return bool(self.state.stable)

    @property
    def pending(self):
        """True while a path is being tracked over several calls (or waits for one)."""
        return self._motion is not None or self._queued is not None

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

    def _cancel_paths(self):
        """Give up the path being tracked and the one waiting (a reset starts over)."""
        if self._motion is not None:
            self._motion.job.cancel()
        self._motion = self._queued = None

    def _settle(self, modules, initial_theta):
        """Settle ``modules`` from ``initial_theta`` as a path of its own (the reset of
        module 0), finished by :meth:`_finish_reset`."""
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
