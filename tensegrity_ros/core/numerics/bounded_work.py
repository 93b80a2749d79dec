"""Bounded work per call: a long computation spread over several calls, paused at check points.

A node's executor must not stall on one command, yet a command (a path across a fold
of a ten-module neck) can need more than a tick.  A :class:`Job` runs a computation
with a deadline per call: :meth:`Job.run` returns when the work is done or, at the
first :func:`checkpoint` past the deadline, with the work paused; the next ``run`` goes
on exactly where it stopped.  So the result is the one an unbounded run gives, bit for
bit, only spread over calls.

How: the first attempt runs on the caller's thread (most commands finish within the
budget: no thread is ever made for them); a checkpoint past its deadline abandons it
(:class:`OutOfTime`), and the work starts over on a worker thread that runs only while
the caller waits for it (a coroutine: never two threads at once, hence deterministic),
paused by the checkpoints.  Python has no stackful coroutine in its standard library,
and the check points lie deep in solver loops, hence the thread.

:func:`checkpoint` is free to call anywhere: outside a job it does nothing.

A :class:`Budget` bounds the work inside a ``with`` block the same way, but gives up
instead of pausing: the first checkpoint past its deadline ends the block (the tracker's
own ``TrackerSettings.time_budget``: the caller then reports the last verified state).
It nests inside a job (the job's check runs first, and may pause there) and inside
another budget.
"""
from __future__ import annotations

import math
import threading

_local = threading.local()


class OutOfTime(BaseException):
    """Raised at a checkpoint to abandon a run (its deadline passed, or it was cancelled).

    A ``BaseException``, like ``asyncio.CancelledError``: solver code that handles its
    own failures with ``except Exception``-style clauses must not swallow it."""


def checkpoint():
    """A safe point of a long computation: the job running it may pause (or stop) here."""
    hook = getattr(_local, 'hook', None)
    if hook is not None:
        hook()


class Job:
    """``work()`` (a function of no arguments) run in slices: see the module docstring.

    ``clock`` returns the current time in the units of the deadlines (seconds of
    ``time.perf_counter`` in use; tests inject a counting clock).
    """

    def __init__(self, work, clock):
        self._work = work
        self._clock = clock
        self._deadline = None
        self._thread = None
        self._go = self._back = None
        self._cancelled = False
        self._result = None
        self._error = None
        self.done = False

    def run(self, deadline):
        """Work until done or until the first checkpoint past ``deadline``; True when done.

        Every call makes progress: a paused job goes on to its next checkpoint at least."""
        self._deadline = deadline
        if self.done:
            return True
        if self._thread is None:
            if self._run_inline():
                return True
            self._start_worker()
        self._go.release()
        self._back.acquire()
        return self.done

    def result(self):
        """What ``work()`` returned (or raise what it raised); only once done."""
        if not self.done:
            raise RuntimeError('the job is not done')
        if self._error is not None:
            raise self._error
        return self._result

    def cancel(self):
        """Abandon a paused job (its worker unwinds through an :class:`OutOfTime`)."""
        if self._thread is not None and not self.done:
            self._cancelled = True
            self._go.release()
            self._back.acquire()
        self.done = True

    # -- inside -------------------------------------------------------------------------

    def _run_inline(self):
        """The first attempt, on the caller's thread; False if it ran out of time."""
        previous = getattr(_local, 'hook', None)
        _local.hook = self._inline_check if self._deadline != math.inf else None
        try:
            self._result = self._work()
        except OutOfTime:
            return False
        except Exception as exc:            # handed to the caller by result()
            self._error = exc
        finally:
            _local.hook = previous
        self.done = True
        return True

    def _inline_check(self):
        if self._clock() > self._deadline:
            raise OutOfTime

    def _start_worker(self):
        self._go, self._back = threading.Semaphore(0), threading.Semaphore(0)
        self._thread = threading.Thread(target=self._worker, name='bounded-work', daemon=True)
        self._thread.start()

    def _worker(self):
        self._go.acquire()
        _local.hook = self._worker_check
        try:
            self._result = self._work()
        except OutOfTime:
            pass
        except Exception as exc:            # handed to the caller by result()
            self._error = exc
        finally:
            self.done = True
            self._back.release()

    def _worker_check(self):
        """Past the deadline: hand control back and wait for the next :meth:`run`."""
        if not self._cancelled and self._clock() > self._deadline:
            self._back.release()
            self._go.acquire()
        if self._cancelled:
            raise OutOfTime


class BudgetSpent(BaseException):
    """Raised at the first checkpoint past a :class:`Budget`'s deadline; ends its block.

    A ``BaseException`` for the reason :class:`OutOfTime` is one; it names its budget,
    so only that budget's block stops there."""

    def __init__(self, budget):
        super().__init__(budget)
        self.budget = budget


class Budget:
    """``with Budget(seconds, clock):`` -- the block ends at its first checkpoint past
    ``seconds`` (in ``clock`` units) from entry; afterwards ``spent`` says whether it did.

    ``seconds=None``: no limit (nothing is installed).  Work between two checkpoints is
    the granularity: the block may overrun its deadline by that much, never more."""

    def __init__(self, seconds, clock):
        self.seconds, self._clock = seconds, clock
        self.spent = False
        self._previous = self._deadline = None

    def __enter__(self):
        if self.seconds is not None:
            self._previous = getattr(_local, 'hook', None)
            self._deadline = self._clock() + self.seconds
            _local.hook = self._check
        return self

    def __exit__(self, kind, error, traceback):
        if self.seconds is not None:
            _local.hook = self._previous
        if isinstance(error, BudgetSpent) and error.budget is self:
            self.spent = True
            return True             # the block ends here; the caller reads ``spent``
        return False

    def _check(self):
        if self._previous is not None:
            self._previous()        # an enclosing job's check first (it may pause)
        if self._clock() > self._deadline:
            raise BudgetSpent(self)
