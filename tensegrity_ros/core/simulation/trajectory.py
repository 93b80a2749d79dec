"""Timed actuator targets: a trajectory played on a simulator, ROS-free.

What JointTrajectoryController's topic interface does with a
``trajectory_msgs/JointTrajectory`` of positions, here for the actuator lengths:

* a :class:`Trajectory` names some modules and gives points, each with one rho per named
  module and a time from the start (strictly increasing, >= 0); it starts at ``start_ns``
  (the message's stamp) or, without one, when it is accepted;
* from where the actuators are when it starts, the targets move linearly in time from
  point to point (positions only: the controller's linear interpolation); the modules it
  does not name keep theirs;
* :class:`TrajectoryPlayer` samples it at every :meth:`~TrajectoryPlayer.advance` (the
  node's timer) and at every point passed since the last one, and commands the simulator
  with the samples: each step is a straight path the tracker follows, so the actuator
  lengths go through every point, and jumps on the way are reported like any command's;
* a new trajectory replaces the running one, an empty one (no points) cancels it, so does
  a direct actuator command to a module it moves, or a reset;
* it has **succeeded** once its last point's time has passed and every module it names
  is at its last position, at rest (a speed limit or the dynamics mode can make that later
  than the last time); it is **aborted** if a step is refused (limits changed meanwhile) or
  a path fails (the state is then the last verified one).

A speed limit (``max_rho_rate``) still applies: a trajectory faster than it is followed
at the limit, late.  Refusals (nothing changes): points of another size than the joints
(``size_mismatch``), times that are negative or do not increase (``trajectory_time``),
non-finite positions (``non_finite``), positions outside [rho_min, rho_max]
(``out_of_range``).
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass
import math

from . import events as ev
from .events import Outcome, TrackingFailure

#: Refusal reasons of a trajectory (besides events.NON_FINITE and OUT_OF_RANGE).
SIZE_MISMATCH = 'size_mismatch'
TRAJECTORY_TIME = 'trajectory_time'

#: States of a trajectory (the words of action goal statuses).
IDLE = 'idle'                   # none accepted yet
EXECUTING = 'executing'
SUCCEEDED = 'succeeded'
ABORTED = 'aborted'
CANCELED = 'canceled'


@dataclass(frozen=True)
class Trajectory:
    """Timed targets of the modules ``joints`` (indices): ``positions[k]`` (one rho per
    joint, m) at ``times_ns[k]`` ns from the start; ``start_ns`` the start time (None: when
    accepted)."""

    joints: tuple
    times_ns: tuple
    positions: tuple
    start_ns: int | None = None

    @property
    def duration_ns(self):
        return self.times_ns[-1] if self.times_ns else 0

    def problem(self):
        """(reason, text) of what makes this trajectory unusable whatever the limits, or
        None: sizes and times (positions are checked against the simulator's limits)."""
        if len(set(self.joints)) != len(self.joints):
            return SIZE_MISMATCH, f'joints {list(self.joints)} repeat'
        if len(self.positions) != len(self.times_ns):
            return SIZE_MISMATCH, (f'{len(self.positions)} points but {len(self.times_ns)} '
                                   f'times')
        for k, row in enumerate(self.positions):
            if len(row) != len(self.joints):
                return SIZE_MISMATCH, (f'point {k} has {len(row)} positions for '
                                       f'{len(self.joints)} joints')
        previous = -1
        for k, t in enumerate(self.times_ns):
            if t < 0:
                return TRAJECTORY_TIME, f'point {k}: time_from_start {t * 1e-9:g} s < 0'
            if t <= previous:
                return TRAJECTORY_TIME, (f'point {k}: time_from_start {t * 1e-9:.9g} s does '
                                         f'not increase (point {k - 1}: '
                                         f'{previous * 1e-9:.9g} s)')
            previous = t
        return None


@dataclass(frozen=True)
class MotionStatus:
    """What the player is doing: ``state`` (IDLE, EXECUTING, SUCCEEDED, ABORTED,
    CANCELED) of trajectory ``number`` (1, 2, ... since the start; 0: none), its
    ``joints`` (module indices), final ``goal`` (one rho per joint), ``duration`` (s, the
    last point's time), ``points`` (count) and ``text`` (why it ended, or what it does)."""

    state: str = IDLE
    number: int = 0
    joints: tuple = ()
    goal: tuple = ()
    duration: float = 0.0
    points: int = 0
    text: str = 'no trajectory yet'


@dataclass(frozen=True)
class MotionEnded:
    """Event: trajectory ``number`` ended (``state`` SUCCEEDED, ABORTED or CANCELED);
    ``module`` is its first joint (for logs), ``text`` says why."""

    number: int
    state: str
    module: int
    text: str


class _Run:
    """A trajectory being played: its start, the actuator lengths it started from, the
    last time it was sampled at and the last targets it commanded."""

    def __init__(self, number, trajectory, start_ns, anchor):
        self.number = number
        self.trajectory = trajectory
        self.start_ns = start_ns
        self.anchor = anchor                # one rho per joint at the start
        self.sampled_ns = None              # time from start of the last sample
        self.commanded = None               # the last targets commanded (a tuple)

    def at(self, t_ns):
        """The targets (one rho per joint) at ``t_ns`` from the start."""
        times, rows = self.trajectory.times_ns, self.trajectory.positions
        k = bisect.bisect_right(times, t_ns)
        if k >= len(times):
            return tuple(rows[-1])
        t0, p0 = (times[k - 1], rows[k - 1]) if k > 0 else (0, self.anchor)
        t1, p1 = times[k], rows[k]
        if t1 <= t0:                        # a first point at t = 0
            return tuple(p1)
        w = (t_ns - t0) / (t1 - t0)
        return tuple(a + w * (b - a) for a, b in zip(p0, p1))


class TrajectoryPlayer:
    """Plays :class:`Trajectory` s on ``simulator`` (a Simulator or DynamicSimulator).

    The caller sends the simulator's actuator commands, resets and time steps through
    the player (:meth:`command_rhos`, :meth:`reset`, :meth:`advance`), so that a direct
    command or a reset can cancel a trajectory; loads and parameters go to the simulator
    itself (a trajectory goes on under them).  Every call returns an
    :class:`~.simulation.events.Outcome`, with a :class:`MotionEnded` among its events when a
    trajectory ends; :attr:`status` is the current :class:`MotionStatus`.
    """

    def __init__(self, simulator):
        self.simulator = simulator
        self.status = MotionStatus()
        self._run = None
        self._count = 0
        self._cause = ''

    # -- what callers send ----------------------------------------------------------------

    def follow(self, trajectory, now_ns, cause='joint_trajectory'):
        """Start ``trajectory`` (replacing the running one; no points: cancel it).
        Refused (nothing changes) for the reasons in the module docstring."""
        if not trajectory.times_ns and not trajectory.positions:
            return self._ended(CANCELED, 'canceled by an empty trajectory')
        refusal = self.refusal(trajectory)
        if refusal is not None:
            return refusal
        replaced = self._ended(CANCELED, f'replaced by trajectory {self._count + 1}')
        self._count += 1
        start = now_ns if trajectory.start_ns is None else trajectory.start_ns
        anchor = tuple(self._actuator(j) for j in trajectory.joints)
        self._run = _Run(self._count, trajectory, start, anchor)
        self._cause = cause
        self.status = MotionStatus(
            state=EXECUTING, number=self._count, joints=tuple(trajectory.joints),
            goal=tuple(trajectory.positions[-1]), duration=trajectory.duration_ns * 1e-9,
            points=len(trajectory.times_ns),
            text=f'{len(trajectory.times_ns)} points over {trajectory.duration_ns * 1e-9:.6g} s')
        return ev.combined([replaced, self._sample(now_ns)])

    def refusal(self, trajectory):
        """What :meth:`follow` would refuse in ``trajectory`` (a refused Outcome), or None."""
        problem = trajectory.problem()
        if problem is not None:
            return ev.refused(*problem)
        for k, row in enumerate(trajectory.positions):
            refused = self.simulator.rhos_refusal(dict(zip(trajectory.joints, row)))
            if refused is not None:
                return ev.refused(refused.reason, f'point {k}: {refused.message}')
        return None

    def command_rhos(self, targets, now_ns, cause):
        """A direct actuator command (:meth:`Simulator.command_rhos`); it cancels the
        running trajectory if it moves one of its modules (unless refused)."""
        outcome = self.simulator.command_rhos(targets, now_ns, cause)
        run = self._run
        if run is None or not outcome.accepted or not set(targets) & set(run.trajectory.joints):
            return outcome
        return ev.combined([self._ended(CANCELED, f'canceled by {cause}'), outcome])

    def reset(self, modules, initial_theta):
        """:meth:`Simulator.reset`; an accepted reset cancels the running trajectory."""
        outcome = self.simulator.reset(modules, initial_theta)
        if not outcome.accepted:
            return outcome
        return ev.combined([self._ended(CANCELED, 'canceled by reset'), outcome])

    def advance(self, now_ns):
        """Sample the running trajectory at ``now_ns`` (commanding the simulator), then
        :meth:`Simulator.advance`; a trajectory that is done has succeeded."""
        sampled = self._sample(now_ns)
        advanced = self.simulator.advance(now_ns)
        return ev.combined([sampled, advanced, self._check(advanced)])

    # -- inside ---------------------------------------------------------------------------

    def _actuator(self, index):
        """Where module ``index``'s actuator is now (moving rods: their live length)."""
        live = getattr(self.simulator, 'live', None)
        return live(index).rho if live is not None else self.simulator.goal(index).rho

    def _sample(self, now_ns):
        """Command the targets at every point passed since the last sample, then at now."""
        run = self._run
        if run is None:
            return Outcome()
        t = now_ns - run.start_ns
        if t < 0:
            return Outcome()
        times = run.trajectory.times_ns
        first = 0 if run.sampled_ns is None else bisect.bisect_right(times, run.sampled_ns)
        last = bisect.bisect_right(times, t)
        outcomes = []
        for when in [times[k] for k in range(first, last)] + [t]:
            targets = run.at(when)
            if targets == run.commanded:
                continue
            run.commanded = targets
            outcome = self.simulator.command_rhos(dict(zip(run.trajectory.joints, targets)),
                                                  now_ns, self._cause)
            if not outcome.accepted:
                return self._ended(ABORTED, f'aborted at {when * 1e-9:.6g} s: '
                                            f'{outcome.message}')
            outcomes.append(outcome)
            if outcome.status == ev.FAILED:
                outcomes.append(self._ended(ABORTED, f'aborted at {when * 1e-9:.6g} s: '
                                                     f'{_failure_text(outcome)}'))
                break
        run.sampled_ns = t
        return ev.combined(outcomes) if outcomes else Outcome()

    def _check(self, advanced):
        """The running trajectory's end: aborted by a failed path, succeeded once done."""
        run = self._run
        if run is None:
            return Outcome()
        if advanced.status == ev.FAILED:
            return self._ended(ABORTED, f'aborted: {_failure_text(advanced)}')
        if run.sampled_ns is None or run.sampled_ns < run.trajectory.duration_ns:
            return Outcome()
        sim = self.simulator
        if sim.pending or getattr(sim, 'moving', False):
            return Outcome()
        goal = run.trajectory.positions[-1]
        for j, rho in zip(run.trajectory.joints, goal):
            if sim.target(j) is not None or not math.isclose(sim.goal(j).rho, rho,
                                                             rel_tol=0.0, abs_tol=1e-12):
                return Outcome()
        reached = ', '.join(f'{sim.names[j]} rho={rho:.6g}'
                            for j, rho in zip(run.trajectory.joints, goal))
        return self._ended(SUCCEEDED, f'reached {reached}')

    def _ended(self, state, text):
        """End the running trajectory (if any) in ``state``: a MotionEnded event."""
        run, self._run = self._run, None
        if run is None:
            return Outcome()
        self.status = MotionStatus(
            state=state, number=run.number, joints=self.status.joints, goal=self.status.goal,
            duration=self.status.duration, points=self.status.points, text=text)
        return Outcome(events=(MotionEnded(number=run.number, state=state,
                                           module=run.trajectory.joints[0], text=text),))


def _failure_text(outcome):
    failures = outcome.of_type(TrackingFailure)
    return failures[0].text if failures else 'a path failed'
