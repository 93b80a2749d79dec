"""The node's command topics: ``<m>/rho_cmd``, ``<m>/force_a3/a4``, ``joint_commands``,
``joint_trajectory`` -> the simulator's (or the trajectory player's) calls.

A command message is first *read* (checked: bad input is rejected and counted), then
*applied* (tracked).  Every callback reads all the commands waiting in its subscription's
queue at once, so that a slow command (a fold) never lets the queue overflow; they are
applied one by one in arrival order (each answered on joint_states) while the callback is
within its time budget, and beyond it only the latest target of a module, the others
coalesced and counted (core.command_coalescing).
"""
from __future__ import annotations

import time

from geometry_msgs.msg import Vector3
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory

from tensegrity_ros.core.simulation.command_coalescing import (BACKLOG_BUDGET_NS, CommandBacklog,
                                                               force_key, target_key)
from tensegrity_ros.log_text import shown
from tensegrity_ros.ros import conversions as conv
from tensegrity_ros.ros.joint_state_names import exact_names, NamesAndPositions
from tensegrity_ros.ros.qos import COMMAND_QOS


class CommandSubscriptions:
    """The command subscriptions of ``node`` and what their messages do.

    ``sim`` and ``player`` are the node's simulator and trajectory player, ``names`` its
    modules; ``incidents`` counts what is refused; ``now_ns`` reads the node clock;
    ``command(outcome, source, now_ns, loads=False)`` reports a command's outcome and
    ``publish_motion`` republishes ``~/motion``.
    """

    def __init__(self, node, *, sim, player, names, incidents, now_ns, command,
                 publish_motion):
        self._sim = sim
        self._player = player
        self._names = names
        self._incidents = incidents
        self._now_ns = now_ns
        self._command = command
        self._publish_motion = publish_motion
        self._logger = node.get_logger()
        self._rho_joints = {f'{m}_rho': i for i, m in enumerate(names)}
        self._read_command_bytes = NamesAndPositions()
        self._kept_joint_indices = None     # (names, what _joint_indices found for them)
        for i, m in enumerate(names):
            self._subscribe(node, Float64, f'{m}/rho_cmd', self._read_rho(i))
            for end in ('a3', 'a4'):
                self._subscribe(node, Vector3, f'{m}/force_{end}', self._read_force(i, end))
        # serialized: joint names are read exactly (rclpy would cut them at a NUL)
        self._subscribe(node, JointState, 'joint_commands', self._read_joint_commands,
                        raw=True)
        self._subscribe(node, JointTrajectory, 'joint_trajectory', self._read_joint_trajectory)

    def _subscribe(self, node, msg_type, topic, read, raw=False):
        """A command subscription whose callback drains its own queue (:meth:`_on_commands`).

        No QoS event handlers: each is a waitable the executor re-adds to its wait set
        before every callback (about 20 us each); QoS mismatches are still reported by the
        peer."""
        made = []
        made.append(node.create_subscription(
            msg_type, topic,
            self._incidents.guard(lambda msg: self._on_commands(made[0], read, msg), topic),
            COMMAND_QOS, raw=raw,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False)))

    def _on_commands(self, subscription, read, first):
        """Callback of a command subscription: ``first`` and every message waiting behind
        it are read with ``read`` (-> (key, apply) or None if rejected), then applied in
        arrival order within the backlog's time budget, beyond it the latest of each key."""
        backlog = CommandBacklog(time.monotonic_ns, BACKLOG_BUDGET_NS)
        for msg in self._waiting_messages(subscription, first):
            command = read(msg)
            if command is not None:
                backlog.offer(*command)
        try:
            backlog.work_off()
        finally:
            self._incidents.counters['commands_coalesced'] += backlog.coalesced

    @staticmethod
    def _waiting_messages(subscription, first):
        """``first``, then the messages already waiting in the subscription's queue (at
        most its depth: newer ones are left for the next callback)."""
        yield first
        for _ in range(COMMAND_QOS.depth):
            with subscription.handle:
                taken = subscription.handle.take_message(subscription.msg_type,
                                                         subscription.raw)
            if taken is None:
                return
            yield taken[0]

    def _reject(self, reason, text):
        return self._incidents.reject(reason, text)

    def _read_rho(self, index):
        topic = f'{self._names[index]}/rho_cmd'

        def read(msg):
            targets = {index: msg.data}
            refusal = self._sim.rhos_refusal(targets)
            if refusal is not None:
                return self._reject(refusal.reason, f'{topic}: {refusal.message}')
            return target_key(targets), lambda: self._apply_targets(targets, topic, 'rho_cmd')
        return read

    def _read_force(self, index, node):
        topic = f'{self._names[index]}/force_{node}'

        def read(msg):                  # z is ignored (planar mechanism)
            force = (msg.x, msg.y)
            refusal = self._sim.force_refusal(index, node, force)
            if refusal is not None:
                return self._reject(refusal.reason, f'{topic}: {refusal.message}')
            return force_key(index, node), lambda: self._apply_force(index, node, force, topic)
        return read

    def _read_joint_commands(self, raw):
        read = self._read_command_bytes(raw)    # one pass over the bytes, names exact
        if read is None:                        # another encoding: rclpy reads it
            msg = deserialize_message(raw, JointState)
            read = exact_names(raw) or msg.name, msg.position
        names, positions = read
        if not names:
            return self._reject('size_mismatch', 'joint_commands: no joint names')
        if len(names) != len(positions):
            return self._reject('size_mismatch', f'joint_commands: {len(names)} names but '
                                                 f'{len(positions)} positions')
        indices, problem = self._joint_indices(names)
        if problem is not None:
            return self._reject(*problem)
        targets = dict(zip(indices, positions))
        refusal = self._sim.rhos_refusal(targets)
        if refusal is not None:
            return self._reject(refusal.reason, f'joint_commands: {refusal.message}')
        return target_key(targets), lambda: self._apply_targets(
            targets, 'joint_commands', 'joint_commands')

    def _read_joint_trajectory(self, msg):
        """A JointTrajectory (JointTrajectoryController's topic interface): ``<m>_rho``
        joints, positions at time_from_start; read into a core Trajectory, checked by the
        player (sizes, times, finite, limits).  No points: cancel the running one."""
        topic = 'joint_trajectory'
        if msg.points and not msg.joint_names:
            return self._reject('size_mismatch', f'{topic}: points but no joint names')
        indices, problem = self._joint_indices(list(msg.joint_names), topic)
        if problem is not None:
            return self._reject(*problem)
        trajectory = conv.trajectory(msg, indices)
        if isinstance(trajectory, tuple):               # (reason, text): a bad message
            return self._reject(trajectory[0], f'{topic}: {trajectory[1]}')
        refusal = self._player.refusal(trajectory) if trajectory.positions else None
        if refusal is not None:
            return self._reject(refusal.reason, f'{topic}: {refusal.message}')
        return ('trajectory',), lambda: self._apply_trajectory(trajectory)

    def _joint_indices(self, names, topic='joint_commands'):
        """(the module index of every joint name, None), or (None, (reason, text)) if a
        name is unknown or given twice; kept for the last list of names (a stream of
        commands repeats the very list: :class:`NamesAndPositions`)."""
        kept = self._kept_joint_indices
        if kept is not None and kept[0] is names:
            return kept[1]
        indices, problem = [], None
        for name in names:
            index = self._rho_joints.get(name)
            if index is None:
                problem = ('unknown_joint', f'{topic}: unknown joint {shown(name)} '
                                            f'(commandable: {sorted(self._rho_joints)})')
                break
            if index in indices:
                problem = ('duplicate_joint', f'{topic}: {shown(name)} given twice')
                break
            indices.append(index)
        found = (None, problem) if problem is not None else (indices, None)
        if topic == 'joint_commands':
            self._kept_joint_indices = (names, found)
        return found

    def _apply_targets(self, targets, source, cause):
        now = self._now_ns()
        self._command(self._player.command_rhos(targets, now, cause), source, now)

    def _apply_force(self, index, node, force, source):
        now = self._now_ns()
        self._command(self._sim.set_force(index, node, force, now), source, now, loads=True)

    def _apply_trajectory(self, trajectory):
        now = self._now_ns()
        outcome = self._player.follow(trajectory, now)
        if outcome.accepted and trajectory.positions:
            self._incidents.counters['trajectories_accepted'] += 1
            self._logger.info(
                f'joint_trajectory {self._player.status.number}: {len(trajectory.times_ns)} '
                f'points over {trajectory.duration_ns * 1e-9:.6g} s')
        self._command(outcome, 'joint_trajectory', now)
        self._publish_motion()
