"""The quasi-static path of a command, tracked ahead in the dynamics mode.

A command's path, tracked by the quasi-static tracker while the rods move, in the calls'
leftover time (a :class:`~.numerics.bounded_work.Job`): its first jump is the early warning (a
:class:`~.simulation.events.JumpAhead`, by the quasi-static mode's rule: a fold or buckling branch
point ahead on the commanded path, warned of before the actuator gets there); its result
is the prediction the rods' rest is compared with.  A command given at rest is tracked
from the rest state; one given while the rods move from the quasi-static equilibrium at
the actuator lengths then, on the branch the rods are on (settled from their angles: the
quasi-static mode's state at the same lengths).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .events import BranchEnd, JumpAhead
from .simulator import SOLVER_ERRORS
from ..numerics.bounded_work import Job


class PathAhead:
    """A command's path from ``start`` (modules) and ``state`` (the rest state; None:
    settled from the moving rods' angles) to ``end``, tracked in ``job``; ``index`` the
    commanded module, ``rho`` its target, ``cause`` the command's."""

    __slots__ = ('start', 'state', 'end', 'job', 'index', 'rho', 'cause', 'warned')

    def __init__(self, start, state, end, job, index, rho, cause):
        self.start, self.state, self.end, self.job = start, state, end, job
        self.index, self.rho, self.cause, self.warned = index, rho, cause, False

    @classmethod
    def from_rest(cls, mechanism, modules, state, targets, index, cause, clock):
        end = tuple(p.with_(rho=float(r)) for p, r in zip(modules, targets))
        job = on_its_own_thread(Job(functools.partial(mechanism.track, modules, end, state),
                                    clock))
        return cls(modules, state, end, job, index, float(targets[index]), cause)

    @classmethod
    def from_motion(cls, mechanism, modules, rhos, thetas, targets, index, cause, clock):
        """From moving rods: ``modules`` (their rho ignored) at actuator lengths ``rhos``,
        local angles ``thetas`` (N x 2)."""
        start = tuple(p.with_(rho=float(r)) for p, r in zip(modules, rhos))
        end = tuple(p.with_(rho=float(r)) for p, r in zip(start, targets))
        job = on_its_own_thread(Job(functools.partial(
            _track_from_angles, mechanism, start, np.array(thetas, dtype=float), end), clock))
        return cls(start, None, end, job, index, float(targets[index]), cause)

    def warning(self, rho):
        """The JumpAhead of the tracked path's first jump if the actuator, at ``rho`` now,
        has not reached it yet; None otherwise (or if tracking failed: the motion will
        meet the trouble and report it)."""
        try:
            motion = self.job.result()
        except SOLVER_ERRORS:
            return None
        if not motion.jumps:
            return None
        kind, _, critical, from_theta, _, _, _ = motion.jumps[0]
        end_rho = float(critical[self.index].rho)
        if (end_rho - rho) * (self.rho - rho) <= 0.0:
            return None                 # already there: the snap says it
        end = BranchEnd(rho=end_rho, kind=kind, modules=tuple(critical),
                        theta=np.reshape(from_theta, (-1, 2)))
        return JumpAhead(module=self.index, rho=self.rho, end=end, cause=self.cause)


def _track_from_angles(mechanism, start, thetas, end):
    """The quasi-static path from the stable equilibrium at ``start`` whose basin holds
    ``thetas`` to ``end`` (a Motion)."""
    return mechanism.track(start, end, mechanism.settle(start, thetas))


def on_its_own_thread(job):
    """``job`` moved to its worker now: a path that takes longer than the rest of a call
    would be tracked twice otherwise (a Job's first attempt on the caller's thread is
    abandoned, not resumed, when it runs out of time)."""
    job.run(-math.inf)
    return job
