"""The ``tensegrity_node``: the ROS layer around the core simulator (interface: msg_docs/).

What the mechanism does -- targets, speed limits, loads, parameter changes, reset,
tracking, jumps, verification -- is decided by :class:`tensegrity_ros.core.simulator.
Simulator` (one module or a neck, one code path, tested without ROS).  This node only maps:

* parameters -> the simulator's configuration (:mod:`tensegrity_ros.ros.parameters`; the
  callbacks that check, apply and read them back: :mod:`tensegrity_ros.ros.parameter_handling`);
* messages -> simulator calls (``<m>/rho_cmd``, ``<m>/force_a3/a4``, ``joint_commands``,
  ``joint_trajectory`` through the core's :class:`~tensegrity_ros.core.trajectory.
  TrajectoryPlayer`, runtime parameter sets, the ``~/reset`` service, the timer);
* the calls' outcomes -> rejections counted in ``/diagnostics``, ``~/jumps`` and
  ``~/motion`` messages, logs; the simulator's state -> ``joint_states``, ``~/equilibrium``,
  ``~/stable``, ``~/head_pose``, ``~/markers``, ``/tf`` and the force parameters (message
  builders: :mod:`tensegrity_ros.ros.conversions`).

The node's own outputs and its service are private (``~/``: under the node's name), so
that two tools in one graph cannot clash; the command topics and ``joint_states`` are
relative (namespaces and remapping work for all of them).

Run:  ``python -m tensegrity_ros.ros.node --ros-args --params-file config/default.yaml``
"""
from __future__ import annotations

import os
import signal
import sys
import time
import traceback

if __name__ == '__main__' or os.path.basename(sys.argv[0]) == 'tensegrity_node':
    # Started as a program: Ctrl-C or SIGTERM while the heavy imports below load (about
    # half a second) is a plain, quiet exit 0; main() installs the real handling.
    signal.signal(signal.SIGINT, lambda *_: os._exit(0))
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, Vector3
import rclpy
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
import rclpy.executors
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
import rclpy.logging
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
import rclpy.utilities
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from tensegrity_ros.core.command_coalescing import (BACKLOG_BUDGET_NS, CommandBacklog, force_key,
                                                    target_key)
from tensegrity_ros.core.events import (Deferred, FAILED, Jump, JumpAhead, Passage,
                                        TrackingFailure, Undecided)
from tensegrity_ros.core.frames import chord_frames
from tensegrity_ros.core.stack import Stack
from tensegrity_ros.core.trajectory import ABORTED, MotionEnded, TrajectoryPlayer
from tensegrity_ros.log_text import clipped, shown
from tensegrity_ros.params_file import check_parameter_file, ConfigError
from tensegrity_ros.ros import conversions as conv, parameters as params, process
from tensegrity_ros.ros.joint_state_names import exact_names, NamesAndPositions
from tensegrity_ros.ros.live_state import LiveStateReports
from tensegrity_ros.ros.parameter_handling import ConfigurationError, ParameterHandling

try:                            # every ROS install has it; the PyPI wheels do not
    from tf2_msgs.msg import TFMessage
except ImportError:
    TFMessage = None

# ---------------------------------------------------------------------------
# QoS (documented in msg_docs/ and README.md)

#: Commands: reliable + volatile, so ``ros2 topic pub`` (and any default publisher)
#: matches.  Depth 1000 = 0.2 s of a 5 kHz stream, the longest a command crossing a fold
#: keeps the node busy on a loaded machine; each callback then reads everything waiting
#: (coalescing superseded targets beyond its time budget), so the queue does not overflow.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Latched status (``stable``, ``equilibrium``): a late subscriber gets the current one.
STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``jumps``: the last 10 jumps are kept for late subscribers.
JUMPS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``joint_states`` and ``/diagnostics``: the usual reliable, volatile stream.
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: ``head_pose``: latched (depth 1), like the status topics: a late subscriber gets the
#: current head pose at once.  Published on every publish_rate tick, at start-up and reset.
HEAD_QOS = STATUS_QOS
#: ``markers``: latched too, so RViz started later still draws the mechanism.
MARKERS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``motion``: latched, so a client that subscribes after sending a trajectory still
#: sees how it ended.
MOTION_QOS = STATUS_QOS
#: ``/tf``: what tf2_ros's TransformBroadcaster uses (DynamicBroadcasterQoS).
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)

DEFAULT_NODE_NAME = 'tensegrity'
#: Start-up check for another node of the same name: every this many seconds, this many
#: times (discovery on loopback usually takes under a second, but several seconds on a
#: loaded machine: a 3 s window missed it there).
NAME_CHECK_PERIOD_SEC = 0.5
NAME_CHECKS = 60
#: Rejected input and failures are logged at most once per this many seconds per reason.
WARN_THROTTLE_SEC = 2.0

#: Reasons counted in ``/diagnostics`` (``rejected_<reason>``).
REJECT_REASONS = (
    'non_finite',            # NaN or inf in a command
    'out_of_range',          # rho outside [rho_min, rho_max]
    'size_mismatch',         # JointState/JointTrajectory: no names, sizes that differ
    'unknown_joint',         # JointState/JointTrajectory: not a commandable <m>_rho
    'duplicate_joint',       # JointState/JointTrajectory: the same joint twice
    'trajectory_time',       # JointTrajectory: time_from_start < 0 or not increasing
    'parameter_type',        # parameter set with the wrong type
    'parameter_read_only',   # parameter set on a read-only parameter
    'parameter_undeclared',  # parameter set on a name the node does not have
    'parameter_delete',      # parameter delete (every parameter is declared, typed)
    'parameter_value',       # parameter value refused (range, physics, limits)
)
#: Trajectory outcomes counted in ``/diagnostics`` (``trajectories_<state>``).
TRAJECTORY_COUNTERS = ('trajectories_accepted', 'trajectories_succeeded',
                       'trajectories_aborted', 'trajectories_canceled')


class TensegrityNode(ParameterHandling, LiveStateReports, Node):
    """ROS 2 node around a core :class:`Simulator`: parameters -> its configuration,
    messages -> its calls, its outcomes -> publishers and logs.

    ``kwargs`` go to :class:`rclpy.node.Node` (``parameter_overrides``, ``namespace``,
    ``cli_args``, ``context`` ...).  Raises :class:`ConfigurationError` if the
    configuration cannot be used (no traceback is printed by :func:`main` then).
    """

    def __init__(self, node_name: str = DEFAULT_NODE_NAME, **kwargs):
        super().__init__(node_name, **kwargs)
        try:
            self._setup()
        except ConfigurationError:
            self.destroy_node()
            raise

    def _setup(self):
        self._node_clock = self.get_clock()
        self._counters = {f'rejected_{r}': 0 for r in REJECT_REASONS}
        self._counters.update(commands_processed=0, commands_coalesced=0,
                              callback_exceptions=0, jump_warnings=0,
                              tracking_failures=0, jumps_total=0, commands_deferred=0,
                              undecided_total=0)
        self._counters.update(dict.fromkeys(TRAJECTORY_COUNTERS, 0))
        self._mirroring = False             # setting parameters to live values
        self._level_events = set()          # what happened since the last /diagnostics
        self._loggers = {}
        self._last_stable = None
        self._hardware_id = self.get_fully_qualified_name()

        self._names = self._declare_modules()
        self._declare_parameters()
        self._dynamics = self.get_parameter('dynamics').value
        self._init_live_state_reports()
        self._warn_unknown_overrides()
        self._sim = self._start_simulator()
        self._player = TrajectoryPlayer(self._sim)
        self._motion_status = conv.MotionStatusBuffer()
        self._published_revision = None     # simulator revision of the last statuses
        self._last_statuses = [None] * len(self._names)
        self._status_buffers = [conv.EquilibriumStatusBuffer() for _ in self._names]
        self._markers = [conv.ModuleMarkers(m) for m in self._names]
        self._head = conv.HeadPose()
        self._rho_joints = {f'{m}_rho': i for i, m in enumerate(self._names)}
        self._read_command_bytes = NamesAndPositions()
        self._kept_joint_indices = None     # (names, what _joint_indices found for them)
        self._js = conv.JointStateBuffer(self._names, velocity=self._dynamics)
        self._create_interfaces()
        self._name_checks = NAME_CHECKS
        self._name_timer = self.create_timer(NAME_CHECK_PERIOD_SEC,
                                             self._guard(self._check_name_unique, 'name check'))
        self._publish_everything()
        for i, m in enumerate(self._names):
            params, eq = self._sim.module(i)
            self.get_logger().info(
                f'{m}: rho={params.rho:.6g} m, theta=({eq.theta1:.6g}, {eq.theta2:.6g}) rad, '
                f'stable, margin {eq.stability_margin:.4g}')

    def _create_interfaces(self):
        """Publishers, subscriptions, the reset service, the timer, parameter callbacks.

        The node's own outputs and its service are private (``~/``), the commands and
        joint_states relative, so that namespaces and remapping work (/diagnostics and /tf
        are absolute by ROS convention).  No per-endpoint QoS event handlers: each is a
        waitable the executor re-adds to its wait set before every callback (about 20 us
        each); QoS mismatches are still reported by the peer.
        """
        def publisher(msg_type, topic, qos):
            return self.create_publisher(
                msg_type, topic, qos,
                event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

        def subscription(msg_type, topic, read, raw=False):
            made = []                   # the callback drains its own subscription
            made.append(self.create_subscription(
                msg_type, topic,
                self._guard(lambda msg: self._on_commands(made[0], read, msg), topic),
                COMMAND_QOS, raw=raw,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False)))

        self._js_pub = publisher(JointState, 'joint_states', STATE_QOS)
        self._stable_pub = publisher(Bool, '~/stable', STATUS_QOS)
        # one latched status per module, published all N together: depth N keeps every
        # module's latest for a late subscriber (N = 1: depth 1, as STATUS_QOS)
        eq_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=len(self._names),
                            reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._eq_pub = publisher(DiagnosticStatus, '~/equilibrium', eq_qos)
        self._jumps_pub = publisher(DiagnosticStatus, '~/jumps', JUMPS_QOS)
        self._diag_pub = publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self._markers_pub = publisher(MarkerArray, '~/markers', MARKERS_QOS)
        self._head_pub = publisher(PoseStamped, '~/head_pose', HEAD_QOS)
        self._motion_pub = publisher(DiagnosticStatus, '~/motion', MOTION_QOS)
        self._tf_pub = publisher(TFMessage, '/tf', TF_QOS) if TFMessage is not None else None
        if self._tf_pub is None:
            self.get_logger().info('tf2_msgs is not installed: no TF on /tf (markers and '
                                   'head_pose carry the frame); a ROS install has it')

        for i, m in enumerate(self._names):
            subscription(Float64, f'{m}/rho_cmd', self._read_rho(i))
            for node in ('a3', 'a4'):
                subscription(Vector3, f'{m}/force_{node}', self._read_force(i, node))
        # serialized: joint names are read exactly (rclpy would cut them at a NUL)
        subscription(JointState, 'joint_commands', self._read_joint_commands, raw=True)
        subscription(JointTrajectory, 'joint_trajectory', self._read_joint_trajectory)
        self.create_service(Trigger, '~/reset', self._on_reset)

        # One timer serves joint_states, speed-limited motion, markers and /diagnostics
        # (fewer wait-set entities = less executor overhead per command).
        self._tick_timer = self.create_timer(
            1.0 / self.get_parameter('publish_rate').value, self._guard(self._on_tick, 'timer'))
        self._set_frames()
        self._watch_parameters()

    def _check_name_unique(self):
        """Start-up: WARN once if another node in the graph has this fully qualified name
        (two nodes with one name share topics, services and parameters unnoticed).  Runs a
        few times while discovery settles, then stops."""
        me = (self.get_name(), self.get_namespace())
        same = sum(1 for entry in self.get_node_names_and_namespaces() if entry == me)
        self._name_checks -= 1
        if same > 1:
            self.get_logger().warning(
                f'another node named {self.get_fully_qualified_name()} is already running '
                f'({same} in the graph): topics, services and parameters are shared; start '
                f'this one under another name or namespace (-r __node:=... / __ns:=...)')
        if same > 1 or self._name_checks <= 0:
            self._name_timer.cancel()
            self.destroy_timer(self._name_timer)

    # -- callbacks, rejections ------------------------------------------------------------

    def _guard(self, callback, what):
        """Wrap a ROS callback: an unexpected exception is logged and counted, never raised."""
        def guarded(*args):
            try:
                return callback(*args)
            except Exception as exc:
                if not self.context.ok():   # shut down under it (Ctrl-C): nothing to report
                    return None
                self._count_exception(what, exc)
        return guarded

    def _count_exception(self, what, exc):
        self._counters['callback_exceptions'] += 1
        self._level_events.add('exception')
        self._throttled('exception').error(clipped(
            f'{what}: unexpected {type(exc).__name__}: {exc} (state unchanged; '
            f'{self._counters["callback_exceptions"]} so far)'),
            throttle_duration_sec=WARN_THROTTLE_SEC)
        self.get_logger().debug(traceback.format_exc())

    def _throttled(self, key):
        """A logger of this node's name with its own throttle state (one per reason)."""
        logger = self._loggers.get(key)
        if logger is None:
            logger = self._loggers[key] = rclpy.logging.get_logger(self.get_logger().name)
        return logger

    def _reject(self, reason, text):
        key = f'rejected_{reason}'
        self._counters[key] += 1
        self._level_events.add('rejected')
        self._throttled(reason).warning(
            clipped(f'{text}: dropped ({key} = {self._counters[key]})'),
            throttle_duration_sec=WARN_THROTTLE_SEC)

    # -- messages -> simulator calls ------------------------------------------------------
    #
    # A command message is first *read* (checked: bad input is rejected and counted), then
    # *applied* (tracked).  Every callback reads all the commands waiting in its
    # subscription's queue at once, so that a slow command (a fold) never lets the queue
    # overflow; they are applied one by one in arrival order (each answered on
    # joint_states) while the callback is within its time budget, and beyond it only the
    # latest target of a module, the others coalesced and counted
    # (core.command_coalescing).

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
            self._counters['commands_coalesced'] += backlog.coalesced

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

    def _apply_trajectory(self, trajectory):
        now = self._now_ns()
        outcome = self._player.follow(trajectory, now)
        if outcome.accepted and trajectory.positions:
            self._counters['trajectories_accepted'] += 1
            self.get_logger().info(
                f'joint_trajectory {self._player.status.number}: {len(trajectory.times_ns)} '
                f'points over {trajectory.duration_ns * 1e-9:.6g} s')
        self._command(outcome, 'joint_trajectory', now)
        self._publish_motion()

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

    def _command(self, outcome, source, now_ns, loads=False):
        """Report a command's outcome: a refusal is counted and dropped; otherwise its
        events are published and the new state goes out stamped ``now_ns``; the design and
        force parameters follow the live values if the command set them (``loads``) or a
        path stopped early."""
        if not outcome.accepted:
            return self._reject(outcome.reason, f'{source}: {outcome.message}')
        self._counters['commands_processed'] += 1
        self._report(outcome)
        self._publish_joint_states(now_ns)
        if loads or outcome.status == FAILED:
            self._sync_parameters()

    def _on_reset(self, request, response):
        try:
            modules, thetas = self._initial_configuration()
            outcome = self._player.reset(modules, thetas)
            if not outcome.accepted:
                response.success = False
                response.message = f'reset failed, state unchanged: {outcome.message}'
                self.get_logger().error(response.message)
                return response
            self._last_stable = None            # republish stable too
            self._report(outcome)
            response.success = True
            if self._sim.pending:               # a long settle: it ends on later ticks
                self._reset_under_way = True
                response.message = ('reset under way: settling takes more than one tick; '
                                    'the state is published when it is reached')
            else:
                self._publish_everything()
                response.message = 'reset to the initial state; ' + '; '.join(
                    self._describe_module(i) for i in range(len(self._names)))
            self.get_logger().info(response.message)
        except Exception as exc:
            self._count_exception('reset', exc)
            response.success = False
            response.message = f'reset failed, state unchanged: {type(exc).__name__}: {exc}'
        return response

    def _describe_module(self, index):
        p, eq = self._sim.module(index)
        return f'{self._names[index]}: rho={p.rho!r} theta=({eq.theta1!r}, {eq.theta2!r})'

    # -- simulator events -> publishers and logs -----------------------------------------

    def _report(self, outcome):
        """Publish and log what a simulator call did (jumps, failures, early warnings)."""
        jumped = False
        for event in outcome.events:
            if isinstance(event, Jump):
                self._report_jump(event)
                jumped = True
            elif isinstance(event, TrackingFailure):
                self._report_tracking_failure(event)
            elif isinstance(event, JumpAhead):
                self._report_jump_ahead(event)
            elif isinstance(event, Deferred):
                self._report_deferred(event)
            elif isinstance(event, Passage):
                self._report_passage(event)
            elif isinstance(event, Undecided):
                self._report_undecided(event)
            elif isinstance(event, MotionEnded):
                self._report_motion_ended(event)
        if jumped:
            self._publish_statuses()

    def _report_motion_ended(self, ended):
        self._counters[f'trajectories_{ended.state}'] += 1
        text = f'joint_trajectory {ended.number} {ended.state}: {ended.text}'
        if ended.state == ABORTED:
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)
        self._publish_motion()

    def _report_jump(self, jump):
        self._counters['jumps_total'] += 1
        m = self._names[jump.module]
        msg = conv.jump_status(name=f'{self.get_name()}: {m} jump',
                               hardware_id=self._hardware_id, modules=self._names, jump=jump)
        self._jumps_pub.publish(msg)
        what = 'jump' if len(self._names) == 1 else 'stack jump'
        self._throttled('jump').warning(f'{m}: {what} ({jump.cause}): {msg.message}',
                                        throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_passage(self, passage):
        """A continuous buckling is no jump (nothing on ``jumps``), but the state left a
        symmetric branch for one side: say so once, at INFO."""
        m = self._names[passage.module]
        rhos = ', '.join(f'{name} rho={p.rho:.6g}'
                         for name, p in zip(self._names, passage.modules))
        self.get_logger().info(f'{m}: passed a branch point continuously ({passage.cause}) at '
                               f'{rhos}: the mechanism buckled smoothly to one side, no jump')

    def _report_undecided(self, undecided):
        """A passage whose side doubles cannot decide: an ``undecided`` message on ``jumps``
        and a WARN line, counted in ``undecided_total``; no jump."""
        self._counters['undecided_total'] += 1
        m = self._names[undecided.module]
        msg = conv.undecided_status(name=f'{self.get_name()}: {m} undecided',
                                    hardware_id=self._hardware_id, modules=self._names,
                                    undecided=undecided)
        self._jumps_pub.publish(msg)
        self._throttled('undecided').warning(f'{m}: {undecided.cause}: {msg.message}',
                                             throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_tracking_failure(self, failure):
        self._count_and_warn('tracking_failures', 'tracking',
                             f'{self._names[failure.module]}: tracking failed ({failure.text}); '
                             f'holding the last verified equilibrium')

    def _report_deferred(self, deferred):
        self._count_and_warn('commands_deferred', 'deferred',
                             f'{self._names[deferred.module]}: {deferred.cause}: '
                             f'{deferred.text}; holding the last verified equilibrium meanwhile')

    def _count_and_warn(self, counter, event, text):
        """Count an event in diagnostics, raise the node status to WARN, log it throttled."""
        self._counters[counter] += 1
        self._level_events.add(event)
        self._throttled(event).warning(text, throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_jump_ahead(self, warning):
        self._counters['jump_warnings'] += 1
        self._throttled('jump_ahead').warning(
            f'{self._names[warning.module]}: {warning.cause} to rho={warning.rho!r} leaves '
            f'the stable branch at rho={warning.end.rho!r} ({warning.end.kind}): the '
            f'mechanism will jump there', throttle_duration_sec=WARN_THROTTLE_SEC)

    # -- publishing -----------------------------------------------------------------------

    def _now_ns(self):
        """The node clock's time (ROS time: simulated under use_sim_time), in ns.

        Read from the clock's handle, as ``Clock.now`` does, without building the
        ``Time`` that ``now()`` wraps it in: ~1.6 instead of ~5.3 us, once per command."""
        clock = self._node_clock.handle
        with clock:
            return clock.get_now().nanoseconds

    def _publish_everything(self):
        """The whole state at once (start-up, reset)."""
        self._publish_joint_states()
        self._publish_head_pose()
        self._publish_tf(self._now_ns())
        self._publish_statuses()
        self._publish_motion()
        self._on_markers_tick()

    def _set_frames(self):
        """Frame names from frame_prefix and frame_id: the root, each top chord, the head."""
        self._frame_id, chords, head = params.frame_names(
            self.get_parameter('frame_prefix').value, self.get_parameter('frame_id').value,
            self._names)
        self._tf = conv.FrameChain(self._frame_id, chords + [head])

    def _publish_tf(self, now_ns):
        """/tf: frame_id -> each module's top chord -> head (core.frames), stamped now."""
        if self._tf_pub is None:
            return
        links = chord_frames([self._sim.module_nodes(i) for i in range(len(self._names))])
        self._tf_pub.publish(TFMessage(transforms=self._tf.update(links, now_ns)))

    def _publish_motion(self):
        """~/motion: the trajectory player's status (latched), when it changed."""
        if self._player.status is self._motion_status.status:
            return
        self._motion_pub.publish(self._motion_status.update(
            name=f'{self.get_name()}: motion', hardware_id=self._hardware_id,
            modules=self._names, status=self._player.status))

    def _publish_statuses(self):
        """equilibrium of every module (all N together, in module order), and stable if
        it changed."""
        for i, m in enumerate(self._names):
            status = self._status_buffers[i].update(
                name=f'{self.get_name()}: {m}', hardware_id=self._hardware_id, module=m,
                status=self._sim.status(i))
            self._last_statuses[i] = status
            self._eq_pub.publish(status)
        self._published_revision = self._sim.revision
        stable = self._sim.stable
        if stable != self._last_stable:
            self._last_stable = stable
            self._stable_pub.publish(Bool(data=stable))

    def _publish_statuses_if_changed(self):
        if self._sim.revision != self._published_revision:
            self._publish_statuses()

    def _on_tick(self):
        now = self._now_ns()
        advanced = self._player.advance(now)
        self._report(advanced)
        self._report_progress()
        self._publish_joint_states(now)
        self._publish_head_pose()
        self._publish_tf(now)
        self._publish_statuses_if_changed()
        if advanced.status == FAILED:       # a path stopped early: loads on the way
            self._sync_parameters()
        for name, action in (('markers_rate', self._on_markers_tick),
                             ('diagnostics_rate', self._publish_diagnostics)):
            entry = self._periodic[name]
            if entry[0] and now >= entry[1]:
                # next due time on the period grid, skipping missed ticks
                entry[1] += entry[0] * max(1, (now - entry[1]) // entry[0] + 1)
                action()

    def _on_markers_tick(self):
        stamp = self._node_clock.now().to_msg()
        markers = []
        for i, status in enumerate(self._last_statuses):
            p = self._sim.modules[i]
            markers.extend(self._markers[i].update(self._sim.module_nodes(i), status.level,
                                                   self._frame_id, stamp, max(p.L1, p.L2)))
        self._markers_pub.publish(conv.marker_array(markers))

    def _publish_head_pose(self):
        """head_pose: midpoint and direction of the top chord A4 -> A3, in the base frame."""
        position, angle = self._sim.head()
        self._head_pub.publish(self._head.update(position, angle, self._frame_id,
                                                 self._node_clock.now().to_msg()))

    def _publish_diagnostics(self):
        events, self._level_events = self._level_events, set()
        progress, extra = self._progress_summary(events)
        if 'exception' in events:
            level, message = conv.ERROR, 'unexpected exception in a callback (see log)'
        elif events:
            parts = []
            if 'rejected' in events:
                parts.append('input rejected')
            if 'tracking' in events:
                parts.append('tracking failed')
            if 'deferred' in events:
                parts.append('a command took more than one tick')
            parts += [progress] if progress else []
            level, message = conv.WARN, ', '.join(parts) + ' since the last report'
        else:
            level, message = conv.OK, 'ok'
        node_status = DiagnosticStatus(level=level, name=f'{self.get_name()}: node',
                                       message=message, hardware_id=self._hardware_id)
        counters = dict(self._counters)
        counters['rejected_total'] = sum(v for k, v in counters.items()
                                         if k.startswith('rejected_'))
        node_status.values = conv.key_values(sorted(counters.items()) + extra)
        self._publish_statuses_if_changed()
        msg = DiagnosticArray(status=[node_status] + self._last_statuses)
        msg.header.stamp = self._node_clock.now().to_msg()
        self._diag_pub.publish(msg)

    # -- introspection (tests, tools) ----------------------------------------------------

    @property
    def modules(self):
        return list(self._names)

    @property
    def simulator(self):
        """The core :class:`Simulator` this node serves (read it; command it via topics)."""
        return self._sim

    def module_state(self, name='m0'):
        """(live ModuleParams, live verified view) of a module: an ``Equilibrium`` for one
        module, a :class:`~tensegrity_ros.core.mechanisms.ModuleView` in a stack."""
        return self._sim.module(self._names.index(name))

    def stack_state(self):
        """(live Stack, live verified StackEquilibrium) of a stack; (None, None) for N = 1."""
        if len(self._names) == 1:
            return None, None
        return Stack(self._sim.modules), self._sim.state

    @property
    def counters(self):
        return dict(self._counters)


def _fatal(text):
    """One FATAL log line (the exit status 2 path of an unusable configuration)."""
    rclpy.logging.get_logger(DEFAULT_NODE_NAME).fatal(clipped(f'invalid configuration: {text}'))


def main(args=None):
    """Entry point of ``tensegrity_node``: 0 on normal exit or Ctrl-C, 2 on a bad configuration."""
    argv = sys.argv if args is None else args
    try:
        for path in process.parameter_files(argv):
            check_parameter_file(path)
        options = process.parse_cli(argv)
    except ConfigError as exc:
        _fatal(exc)
        return 2
    except _rclpy.RCLInvalidROSArgsError as exc:    # what rcl refuses beyond the YAML check
        _fatal(str(exc).split(', at /')[0])
        return 2
    node = None
    executor = None
    try:
        # SIGINT and SIGTERM: rclpy's handlers, installed by rclpy.init, shut the context
        # down first and then chain to this one.
        interrupt = process.Interrupt()
        signal.signal(signal.SIGINT, interrupt)
        signal.signal(signal.SIGTERM, interrupt)
        rclpy.init(args=argv)
        node = TensegrityNode()
        executor = process.make_executor(options.executor)
        executor.add_node(node)
        interrupt.spinning = True
        # spin_once in a loop rather than spin(): the events executor's spin() does not
        # return on a shutdown from the SIGINT/SIGTERM handler, spin_once does.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except ConfigurationError as exc:
        _fatal(exc)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A SIGINT/SIGTERM that arrives while the node is starting shuts the context down
        # under it (e.g. "publisher's context is invalid"): that is a normal exit.
        if rclpy.ok():
            raise
    finally:
        process.quietly(executor.shutdown if executor is not None else None)
        process.quietly(node.destroy_node if node is not None else None)
        process.quietly(rclpy.try_shutdown)
    return 0


if __name__ == '__main__':
    sys.exit(main())
