"""Commands that arrive faster than they are tracked: only the latest target of a module matters.

A command can take milliseconds (a path across a fold), while a robot stack may send
thousands a second.  Rather than let the transport's queue overflow (commands lost
without a trace), the node reads every command waiting in a queue at once and offers
them here, in arrival order.  A command replaces a waiting one with the same key:

* actuator targets: the key is the set of modules they name (``rho_cmd`` of ``m0`` and a
  ``joint_commands`` naming only ``m0_rho`` share it; one naming ``m0_rho`` and
  ``m2_rho`` has a key of its own);
* forces: the key is (module, loaded node).

The replaced command is *coalesced*: counted, never tracked.  The rest are applied in
the order of their latest arrival.  So every offered command is either applied or
counted: ``applied + coalesced == offered``.  ROS-free.
"""
from __future__ import annotations


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
