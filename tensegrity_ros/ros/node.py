"""The ``tensegrity_node``: the ROS layer around the core simulator (interface: msg_docs/).

What the mechanism does -- targets, speed limits, loads, parameter changes, reset,
tracking, jumps, verification -- is decided by :class:`tensegrity_ros.core.simulation.simulator.
Simulator` (one module or a neck, one code path, tested without ROS).  This node only maps:

* parameters -> the simulator's configuration (:mod:`tensegrity_ros.ros.parameters`; the
  callbacks that check, apply and read them back: :mod:`tensegrity_ros.ros.parameter_handling`);
* messages -> simulator calls (``<m>/rho_cmd``, ``<m>/force_a3/a4``, ``joint_commands``,
  ``joint_trajectory`` through the core's :class:`~tensegrity_ros.core.simulation.trajectory.
  TrajectoryPlayer`: :mod:`tensegrity_ros.ros.commands`; runtime parameter sets, the
  ``~/reset`` service, the timer: here);
* the calls' outcomes -> rejections and failures counted in ``/diagnostics``
  (:mod:`tensegrity_ros.ros.incidents`), ``~/jumps`` and ``~/motion`` messages, logs
  (:mod:`tensegrity_ros.ros.event_reports`); the simulator's state -> ``joint_states``,
  ``~/equilibrium``, ``~/stable``, ``~/head_pose``, ``~/markers``, ``/tf`` and the force
  parameters (here and :mod:`tensegrity_ros.ros.live_state`; message builders:
  :mod:`tensegrity_ros.ros.conversions`, :mod:`tensegrity_ros.ros.visuals`; QoS:
  :mod:`tensegrity_ros.ros.qos`).

The node's own outputs and its service are private (``~/``: under the node's name), so
that two tools in one graph cannot clash; the command topics and ``joint_states`` are
relative (namespaces and remapping work for all of them).

Run:  ``python -m tensegrity_ros.ros.node --ros-args --params-file config/default.yaml``
"""
from __future__ import annotations

import os
import signal
import sys

if __name__ == '__main__' or os.path.basename(sys.argv[0]) == 'tensegrity_node':
    # Started as a program: Ctrl-C or SIGTERM while the heavy imports below load (about
    # half a second) is a plain, quiet exit 0; main() installs the real handling.
    signal.signal(signal.SIGINT, lambda *_: os._exit(0))
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
import rclpy
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
import rclpy.logging
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from tensegrity_ros.core.neck.frames import chord_frames
from tensegrity_ros.core.neck.stack import Stack
from tensegrity_ros.core.simulation.events import FAILED
from tensegrity_ros.core.simulation.trajectory import TrajectoryPlayer
from tensegrity_ros.log_text import clipped
from tensegrity_ros.params_file import check_parameter_file, ConfigError
from tensegrity_ros.ros import conversions as conv, parameters as params, process, visuals
from tensegrity_ros.ros.commands import CommandSubscriptions
from tensegrity_ros.ros.event_reports import EventReports
from tensegrity_ros.ros.incidents import Incidents
from tensegrity_ros.ros.live_state import LiveStateReports
from tensegrity_ros.ros.parameter_handling import ConfigurationError, ParameterHandling
from tensegrity_ros.ros.qos import (equilibrium_qos, HEAD_QOS, JUMPS_QOS, MARKERS_QOS, MOTION_QOS,
                                    STATE_QOS, STATUS_QOS, TF_QOS)

try:                            # every ROS install has it; the PyPI wheels do not
    from tf2_msgs.msg import TFMessage
except ImportError:
    TFMessage = None

DEFAULT_NODE_NAME = 'tensegrity'
#: Start-up check for another node of the same name: every this many seconds, this many
#: times (discovery on loopback usually takes under a second, but several seconds on a
#: loaded machine: a 3 s window missed it there).
NAME_CHECK_PERIOD_SEC = 0.5
NAME_CHECKS = 60


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
        self._incidents = Incidents(self.get_logger(), self.context)
        self._mirroring = False             # setting parameters to live values
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
        self._markers = [visuals.ModuleMarkers(m) for m in self._names]
        self._head = visuals.HeadPose()
        self._js = conv.JointStateBuffer(self._names, velocity=self._dynamics)
        self._create_interfaces()
        self._name_checks = NAME_CHECKS
        self._name_timer = self.create_timer(
            NAME_CHECK_PERIOD_SEC, self._incidents.guard(self._check_name_unique, 'name check'))
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

        self._js_pub = publisher(JointState, 'joint_states', STATE_QOS)
        self._stable_pub = publisher(Bool, '~/stable', STATUS_QOS)
        self._eq_pub = publisher(DiagnosticStatus, '~/equilibrium',
                                 equilibrium_qos(len(self._names)))
        jumps_pub = publisher(DiagnosticStatus, '~/jumps', JUMPS_QOS)
        self._diag_pub = publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self._markers_pub = publisher(MarkerArray, '~/markers', MARKERS_QOS)
        self._head_pub = publisher(PoseStamped, '~/head_pose', HEAD_QOS)
        self._motion_pub = publisher(DiagnosticStatus, '~/motion', MOTION_QOS)
        self._tf_pub = publisher(TFMessage, '/tf', TF_QOS) if TFMessage is not None else None
        if self._tf_pub is None:
            self.get_logger().info('tf2_msgs is not installed: no TF on /tf (markers and '
                                   'head_pose carry the frame); a ROS install has it')
        self._events = EventReports(
            node_name=self.get_name(), hardware_id=self._hardware_id, names=self._names,
            jumps_pub=jumps_pub, incidents=self._incidents, logger=self.get_logger(),
            publish_statuses=self._publish_statuses, publish_motion=self._publish_motion)
        self._commands = CommandSubscriptions(
            self, sim=self._sim, player=self._player, names=self._names,
            incidents=self._incidents, now_ns=self._now_ns, command=self._command,
            publish_motion=self._publish_motion)
        self.create_service(Trigger, '~/reset', self._on_reset)

        # One timer serves joint_states, speed-limited motion, markers and /diagnostics
        # (fewer wait-set entities = less executor overhead per command).
        self._tick_timer = self.create_timer(
            1.0 / self.get_parameter('publish_rate').value,
            self._incidents.guard(self._on_tick, 'timer'))
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

    def _command(self, outcome, source, now_ns, loads=False):
        """Report a command's outcome: a refusal is counted and dropped; otherwise its
        events are published and the new state goes out stamped ``now_ns``; the design and
        force parameters follow the live values if the command set them (``loads``) or a
        path stopped early."""
        if not outcome.accepted:
            return self._incidents.reject(outcome.reason, f'{source}: {outcome.message}')
        self._incidents.counters['commands_processed'] += 1
        self._events.report(outcome)
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
            self._events.report(outcome)
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
            self._incidents.exception('reset', exc)
            response.success = False
            response.message = f'reset failed, state unchanged: {type(exc).__name__}: {exc}'
        return response

    def _describe_module(self, index):
        p, eq = self._sim.module(index)
        return f'{self._names[index]}: rho={p.rho!r} theta=({eq.theta1!r}, {eq.theta2!r})'

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
        self._tf = visuals.FrameChain(self._frame_id, chords + [head])

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
        self._events.report(advanced)
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
        self._markers_pub.publish(visuals.marker_array(markers))

    def _publish_head_pose(self):
        """head_pose: midpoint and direction of the top chord A4 -> A3, in the base frame."""
        position, angle = self._sim.head()
        self._head_pub.publish(self._head.update(position, angle, self._frame_id,
                                                 self._node_clock.now().to_msg()))

    def _publish_diagnostics(self):
        events = self._incidents.take_level_events()
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
        counters = dict(self._incidents.counters)
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
        module, a :class:`~tensegrity_ros.core.simulation.mechanisms.ModuleView` in a stack."""
        return self._sim.module(self._names.index(name))

    def stack_state(self):
        """(live Stack, live verified StackEquilibrium) of a stack; (None, None) for N = 1."""
        if len(self._names) == 1:
            return None, None
        return Stack(self._sim.modules), self._sim.state

    @property
    def counters(self):
        return dict(self._incidents.counters)


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
