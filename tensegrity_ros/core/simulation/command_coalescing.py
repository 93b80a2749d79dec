"""Commands that arrive faster than they are tracked: each answered in order while that
stays quick, only the latest target of a module beyond.

A command can take milliseconds (a path across a fold), while a robot stack may send
thousands a second.  Rather than let the transport's queue overflow (commands lost
without a trace), the node reads every command waiting in a queue at once and offers
them to a :class:`CommandBacklog`, in arrival order.  The backlog applies them one by
one, in that order, while the callback is within :data:`BACKLOG_BUDGET_NS` of its start
(a short burst -- a scheduling stall of a few ms at 1 kHz -- is answered command by
command).  From the first command that finds the budget spent, the rest are
coalesced (:class:`LatestCommands`): a command replaces a waiting one with the same key,

* actuator targets: the key is the set of modules they name (``rho_cmd`` of ``m0`` and a
  ``joint_commands`` naming only ``m0_rho`` share it; one naming ``m0_rho`` and
  ``m2_rho`` has a key of its own);
* forces: the key is (module, loaded node).

The replaced command is *coalesced*: counted, never tracked.  The survivors are applied
in the order of their latest arrival.  So every offered command is either applied or
counted: ``applied + coalesced == offered``.  ROS-free; the clock is injected.
"""
from __future__ import annotations

from collections import deque

#: How long (ns, from the callback's start) waiting commands are still applied one by
#: one.  10 ms = 10 commands of a 1 kHz stream: a backlog left by a scheduling stall of a
#: few ms (4-5.5 ms bursts measured on a shared 2-core machine, where a small neck command
#: costs the node ~0.5 ms) is worked off inside it, every command answered; a command is
#: then answered at most ~one budget after it was read.  Beyond it (a fold taking ~15 ms,
#: a flood) only the latest target per key is tracked, so a callback stays within the
#: budget plus one command plus the survivors, far inside the 0.2 s the command queue
#: holds at 5 kHz: the queue cannot overflow, the executor does not stall.  The price of
#: a larger budget is latency: while the machine cannot give the node the CPU a stream
#: needs, answers run up to ~1-2 budgets late instead of being coalesced.
BACKLOG_BUDGET_NS = 10_000_000


def target_key(modules):
    """Key of actuator targets for the modules (indices) they name."""
    return ('rho', tuple(sorted(modules)))


def force_key(module, node):
    """Key of a force at node ``'a3'`` or ``'a4'`` of a module."""
    return ('force', module, node)


class LatestCommands:
    """Commands waiting to be applied, one per key (the latest); counts the replaced ones."""

    def __init__(self):
        self._waiting = {}
        self.offered = 0
        self.coalesced = 0

    def offer(self, key, command):
        """Add a command; it replaces (coalesces) a waiting one with the same key."""
        self.offered += 1
        if key in self._waiting:
            del self._waiting[key]          # re-inserted below: order of latest arrival
            self.coalesced += 1
        self._waiting[key] = command

    def take(self):
        """The waiting commands in the order of their latest arrival; none wait after."""
        commands = list(self._waiting.values())
        self._waiting.clear()
        return commands

    def __len__(self):
        return len(self._waiting)


class CommandBacklog:
    """The commands one callback read, applied in arrival order within a time budget.

    ``clock`` returns the time in ns (the node: ``time.monotonic_ns``, wall time even
    under simulated ROS time; tests inject a fake one); the budget runs from when the
    backlog is made, i.e. the callback's start.  A command is a callable that applies it.
    """

    def __init__(self, clock, budget_ns=BACKLOG_BUDGET_NS):
        self._clock = clock
        self._deadline = clock() + budget_ns
        self._waiting = deque()             # (key, command) in arrival order
        self.offered = 0
        self.applied = 0
        self.coalesced = 0
        self.beyond_budget = False          # the budget was found spent: coalescing

    def offer(self, key, command):
        """Add a command (in arrival order) under its coalescing key."""
        self.offered += 1
        self._waiting.append((key, command))

    def work_off(self):
        """Apply the waiting commands: each in turn while the budget lasts, then the latest
        of each key among the rest (the others counted as coalesced).  A command that
        raises stops the work-off; the ones behind it stay waiting."""
        while self._waiting:
            if not self.beyond_budget and self._clock() >= self._deadline:
                self.beyond_budget = True
                self._keep_latest()
                continue
            _, command = self._waiting.popleft()
            self.applied += 1
            command()

    def _keep_latest(self):
        """Of the waiting commands, keep the latest of each key (order of latest arrival)."""
        latest = LatestCommands()
        for key, command in self._waiting:
            latest.offer(key, (key, command))
        self.coalesced += latest.coalesced
        self._waiting = deque(latest.take())

    def __len__(self):
        """How many commands wait (0 after :meth:`work_off`)."""
        return len(self._waiting)
