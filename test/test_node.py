"""Launch-less tests of the tensegrity node, driven through its topics, services and parameters.

Every test creates the node in-process with its own namespace, plus a client node that
talks to it exactly as ``ros2 topic pub`` / ``ros2 topic echo`` / ``ros2 param set``
would (reliable, volatile publishers; transient-local subscribers for the latched
status).  Both are spun by one SingleThreadedExecutor until a condition holds or a
generous timeout expires: no sleeps are used for synchronisation.
"""
import itertools
import math
import os
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3
import pytest
from rcl_interfaces.msg import Log, ParameterType
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from tensegrity_ros.core import ModuleParams, settle, track_module
from tensegrity_ros.ros.node import ConfigurationError, TensegrityNode

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CONFIG = ROOT / 'config' / 'default.yaml'
TIMEOUT = float(os.environ.get('TENSEGRITY_TEST_TIMEOUT', '30'))

#: What ``ros2 topic pub`` uses by default: reliable, volatile.
PUB_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
#: What ``ros2 topic echo`` picks for a transient-local publisher.
LATCHED_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
STREAM_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)

_namespaces = itertools.count()


def values(status):
    return {kv.key: kv.value for kv in status.values}


def fig8a_overrides(**extra):
    """Fig. 8a: L1 = L2 = 1, k = 100, F3 = F4 = 5 N (pulling), lower branch at rho = 0.5."""
    params = {'m0.force_a3': [0.0, 5.0], 'm0.force_a4': [0.0, 5.0], 'm0.rho_initial': 0.5,
              'm0.initial_theta': [-1.0, -1.0]}
    params.update(extra)
    return params


class Harness:
    """A node under test plus a client node, spun together."""

    def __init__(self, parameters=None, namespace=None, cli_args=None, node=True,
                 executor=None):
        self.own_executor = executor is None
        self.executor = executor or SingleThreadedExecutor()
        self.ns = namespace or f'/t{next(_namespaces)}_{os.getpid()}'
        self.nodes = []
        overrides = {'diagnostics_rate': 20.0}
        overrides.update(parameters or {})
        self.node = None
        if node:
            self.node = TensegrityNode(
                namespace=self.ns, cli_args=cli_args,
                parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
            self.add(self.node)
        self.client = rclpy.create_node(f'client_{next(_namespaces)}', namespace=self.ns)
        self.add(self.client)
        c = self.client
        self.rho_pub = c.create_publisher(Float64, 'm0/rho_cmd', PUB_QOS)
        self.force_pubs = {w: c.create_publisher(Vector3, f'm0/force_{w}', PUB_QOS)
                           for w in ('a3', 'a4')}
        self.jc_pub = c.create_publisher(JointState, 'joint_commands', PUB_QOS)
        self.joint_states, self.stable, self.equilibrium, self.jumps = [], [], [], []
        self.undecided = []     # ``jumps`` messages of kind 'undecided' (not jumps)
        self.diagnostics, self.markers = [], []
        c.create_subscription(JointState, 'joint_states', self.joint_states.append, STREAM_QOS)
        # the node's own outputs and service are private: <ns>/tensegrity/<name>
        c.create_subscription(Bool, self.private('stable'), self.stable.append, LATCHED_QOS)
        c.create_subscription(DiagnosticStatus, self.private('equilibrium'),
                              self.equilibrium.append, LATCHED_QOS)
        c.create_subscription(DiagnosticStatus, self.private('jumps'), self._on_jumps,
                              LATCHED_QOS)
        c.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, STREAM_QOS)
        c.create_subscription(MarkerArray, self.private('markers'), self.markers.append,
                              LATCHED_QOS)
        self.log = []
        c.create_subscription(Log, '/rosout', self._on_log, STREAM_QOS)
        self.reset_client = c.create_client(Trigger, self.private('reset'))
        self.params = AsyncParameterClient(c, f'{self.ns}/tensegrity')

    def private(self, name):
        """The full name of the node's private topic or service ``name`` (``~/name``)."""
        return f'{self.ns}/tensegrity/{name}'

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)

    def close(self):
        for node in self.nodes:
            self.executor.remove_node(node)
            node.destroy_node()
        if self.own_executor:
            self.executor.shutdown()

    def _on_diagnostics(self, msg):
        # other test sessions may share the domain: keep only our node's statuses
        if self.node and any(s.hardware_id == self.node.get_fully_qualified_name()
                             for s in msg.status):
            self.diagnostics.append(msg)

    def _on_log(self, msg):
        if self.node and msg.name == self.node.get_logger().name:
            self.log.append(msg)

    def _on_jumps(self, msg):
        undecided = values(msg)['kind'] == 'undecided'
        (self.undecided if undecided else self.jumps).append(msg)

    def warnings(self, text):
        return [m.msg for m in self.log if m.level == Log.WARN and text in m.msg]

    # -- spinning -------------------------------------------------------------------------

    def spin_until(self, predicate, timeout=TIMEOUT, what='condition'):
        clock = self.client.get_clock()
        deadline = clock.now().nanoseconds + int(timeout * 1e9)
        while not predicate():
            if clock.now().nanoseconds > deadline:
                raise AssertionError(f'timed out after {timeout} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.05)

    def ready(self):
        """Discovery done: every command publisher is matched and the status is latched in."""
        pubs = [self.rho_pub, self.jc_pub, *self.force_pubs.values()]
        self.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs)
                        and self.joint_states and self.equilibrium and self.stable,
                        what='discovery and the first status')
        return self

    # -- state ----------------------------------------------------------------------------

    def state(self):
        """(rho, theta1, theta2, actuator_force) of the last joint_states."""
        msg = self.joint_states[-1]
        assert list(msg.name) == ['m0_rho', 'm0_theta1', 'm0_theta2']
        return (msg.position[0], msg.position[1], msg.position[2], msg.effort[0])

    def eq(self):
        return values(self.equilibrium[-1])

    def counter(self, key):
        if not self.diagnostics:
            return None
        node_status = next(s for s in self.diagnostics[-1].status if s.name.endswith(': node'))
        return int(values(node_status)[key])

    # -- commands -------------------------------------------------------------------------

    def command_rho(self, rho, expect=None):
        """Publish rho_cmd and wait for the joint_states that reports ``expect`` (default rho)."""
        n = len(self.joint_states)
        self.rho_pub.publish(Float64(data=float(rho)))
        target = rho if expect is None else expect
        self.spin_until(lambda: any(m.position[0] == target for m in self.joint_states[n:]),
                        what=f'joint_states with rho={target}')
        return self.state()

    def wait_status(self, predicate, what='equilibrium status'):
        self.spin_until(lambda: self.equilibrium and predicate(self.eq()), what=what)
        return self.eq()

    def rejected(self, key, send):
        """Send bad input; wait until /diagnostics counts it; the state must not change."""
        self.spin_until(lambda: self.counter(key) is not None, what='/diagnostics')
        before_count = self.counter(key)
        before_state = self.node.module_state()
        send()
        self.spin_until(lambda: self.counter(key) == before_count + 1,
                        what=f'{key} to reach {before_count + 1}')
        assert self.node.module_state() == before_state
        n = len(self.joint_states)
        self.spin_until(lambda: len(self.joint_states) > n, what='a timer joint_states')
        assert self.state()[:3] == (before_state[0].rho, before_state[1].theta1,
                                    before_state[1].theta2)
        return self.counter('rejected_total')

    def call(self, future, what):
        self.spin_until(future.done, what=what)
        return future.result()


# ---------------------------------------------------------------------------
# Start-up, latched status, the default configuration


def test_starts_on_the_upper_branch_and_latches_status(harness):
    h = harness().ready()
    rho, t1, t2, force = h.state()
    assert rho == 0.75
    # unloaded, L1 = L2 = 1: the stable pair is the parallelogram with cos(theta) = rho
    assert t1 == pytest.approx(math.acos(0.75), abs=1e-9)
    assert t2 == pytest.approx(math.acos(0.75), abs=1e-9)
    assert force == pytest.approx(-75.0, abs=1e-6)
    assert h.stable[-1].data is True
    v = h.eq()
    assert h.equilibrium[-1].level == DiagnosticStatus.OK
    for key in ('module', 'rho', 'theta1', 'theta2', 'stability_margin', 'eigenvalues',
                'residual', 'actuator_force', 'num_equilibria', 'num_stable', 'f3x', 'f3y',
                'f4x', 'f4y', 'last_jump_kind', 'last_jump_rho', 'jumps_total'):
        assert key in v, key
    assert v['module'] == 'm0'
    assert float(v['theta1']) == t1            # repr precision: exact round trip
    assert float(v['stability_margin']) == pytest.approx(87.5)
    assert (int(v['num_equilibria']), int(v['num_stable'])) == (6, 2)
    assert v['last_jump_kind'] == 'none' and v['jumps_total'] == '0'
    assert float(v['residual']) < 1e-10


def test_initial_theta_picks_the_lower_branch(harness):
    h = harness({'m0.initial_theta': [-0.5, -0.6]}).ready()
    _, t1, t2, _ = h.state()
    assert t1 == pytest.approx(-math.acos(0.75), abs=1e-9)
    assert t2 == pytest.approx(-math.acos(0.75), abs=1e-9)


def test_late_subscriber_gets_latched_stable_and_equilibrium(harness):
    h = harness().ready()
    h.command_rho(0.8)
    h.wait_status(lambda v: float(v['rho']) == 0.8)
    late = harness(namespace=h.ns, node=False, executor=h.executor)   # subscribes only now
    h.spin_until(lambda: late.stable and late.equilibrium, what='latched status')
    assert late.stable[-1].data is True
    assert float(values(late.equilibrium[-1])['rho']) == 0.8
    h.spin_until(lambda: late.markers, what='latched markers')


def test_node_from_the_default_config_file(harness):
    h = harness(cli_args=['--ros-args', '--params-file', str(DEFAULT_CONFIG)]).ready()
    node = h.node
    assert node.get_name() == 'tensegrity'
    assert node.get_parameter('modules').value == ['m0']
    assert node.get_parameter('m0.L1').value == 1.0
    assert node.get_parameter('m0.L2').value == 1.0
    assert node.get_parameter('m0.k').value == 100.0
    assert list(node.get_parameter('m0.force_a3').value) == [0.0, 0.0]
    assert node.get_parameter('publish_rate').value == 50.0
    assert node.get_parameter('frame_id').value == 'tensegrity_base'
    params, eq = node.module_state()
    assert (params.ka, params.kb, params.kc) == (100.0, 100.0, 100.0)
    assert h.state()[:3] == (0.75, eq.theta1, eq.theta2)
    assert eq.theta1 == pytest.approx(math.acos(0.75), abs=1e-9)
    # the file's read-only modules parameter is described and refuses changes
    assert node.describe_parameter('modules').read_only
    assert not node.set_parameters([Parameter('modules', value=['m1'])])[0].successful


def test_two_nodes_in_different_namespaces(harness):
    left = harness(namespace=f'/left_{os.getpid()}').ready()
    right = harness(namespace=f'/right_{os.getpid()}', parameters={'m0.rho_initial': 0.9},
                    executor=left.executor).ready()
    left.command_rho(0.6)
    assert left.state()[0] == 0.6
    n = len(right.joint_states)
    left.spin_until(lambda: len(right.joint_states) > n + 2, what='right timer states')
    assert right.state()[0] == 0.9
    right.command_rho(1.2)
    left.spin_until(lambda: len(left.joint_states) > 3, what='left states')
    assert left.state()[0] == 0.6 and right.state()[0] == 1.2
    assert left.node.get_fully_qualified_name() != right.node.get_fully_qualified_name()


# ---------------------------------------------------------------------------
# Commands through topics


def test_rho_cmd_moves_along_the_branch(harness):
    h = harness().ready()
    rho, t1, t2, force = h.command_rho(0.9)
    assert rho == 0.9
    assert t1 == pytest.approx(math.acos(0.9), abs=1e-8)
    assert t2 == pytest.approx(math.acos(0.9), abs=1e-8)
    params, eq = h.node.module_state()
    assert force == eq.actuator_force
    v = h.wait_status(lambda v: float(v['rho']) == 0.9)
    assert float(v['theta1']) == t1
    assert not h.jumps


def test_joint_commands_sets_rho(harness):
    h = harness().ready()
    h.jc_pub.publish(JointState(name=['m0_rho'], position=[0.6]))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.6, what='rho 0.6')
    assert h.state()[1] == pytest.approx(math.acos(0.6), abs=1e-8)


def test_force_topics_are_tracked(harness):
    h = harness().ready()
    start, eq0 = h.node.module_state()
    h.force_pubs['a3'].publish(Vector3(x=1.0, y=-3.0, z=123.0))    # z ignored
    h.wait_status(lambda v: float(v['f3y']) == -3.0)
    h.force_pubs['a4'].publish(Vector3(x=0.5, y=2.0, z=float('nan')))
    v = h.wait_status(lambda v: float(v['f4y']) == 2.0)
    assert (float(v['f3x']), float(v['f4x'])) == (1.0, 0.5)
    expected = track_module(start, start.with_(f3x=1.0, f3y=-3.0), eq0.theta)
    expected = track_module(expected.end, expected.end.with_(f4x=0.5, f4y=2.0),
                            expected.final.theta)
    assert float(v['theta1']) == pytest.approx(expected.final.theta1, abs=1e-9)
    assert float(v['theta2']) == pytest.approx(expected.final.theta2, abs=1e-9)
    h.spin_until(lambda: h.state()[1] == float(v['theta1']), what='joint_states')


# ---------------------------------------------------------------------------
# Fig. 8a through topics: branch point C1, hysteresis, fold C2


def _core_jumps(rho0, theta0, rho1, **forces):
    p0 = ModuleParams(rho=rho0, **forces)
    return track_module(p0, p0.with_(rho=rho1), settle(p0, theta0).theta).jumps


def test_command_answers_are_stamped_with_ros_time_under_use_sim_time(harness):
    """With use_sim_time the node's clock is /clock's: a command's joint_states carries
    the simulated time that was current when it was tracked (not the wall clock)."""
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock
    h = harness({'use_sim_time': True})     # not ready(): no ticks while /clock stands still
    clock_pub = h.client.create_publisher(Clock, '/clock', STREAM_QOS)
    h.spin_until(lambda: h.rho_pub.get_subscription_count() > 0, what='discovery')
    sim_ns = 1234 * 10**9 + 5678
    # /clock is shared by the domain: keep publishing until the node's clock shows it
    h.spin_until(lambda: clock_pub.publish(Clock(clock=Time(sec=1234, nanosec=5678))) or
                 h.node.get_clock().now().nanoseconds == sim_ns, what='the simulated time')
    h.command_rho(0.8)
    answer = next(m for m in h.joint_states if m.position[0] == 0.8)
    assert (answer.header.stamp.sec, answer.header.stamp.nanosec) == (1234, 5678)


def test_fig8a_branch_point_then_hysteresis(harness):
    h = harness(fig8a_overrides()).ready()
    _, t1, t2, _ = h.state()
    assert t1 < 0 and t2 < 0                          # lower branch
    expected = _core_jumps(0.5, [-1.0, -1.0], 0.1, f3y=5.0, f4y=5.0)
    assert [j.kind for j in expected] == ['branch_point']

    rho, t1, t2, _ = h.command_rho(0.1)
    assert rho == 0.1
    h.spin_until(lambda: h.jumps, what='a jumps message')
    assert len(h.jumps) == 1
    jump = values(h.jumps[0])
    assert jump['module'] == 'm0'
    assert jump['kind'] == 'branch_point'
    assert float(jump['rho']) == pytest.approx(float(expected[0].params.rho), abs=1e-9)
    assert 0.1 < float(jump['rho']) < 0.2            # C1 of fig. 8a (about 0.155)
    assert float(jump['from_theta1']) < 0 and float(jump['from_theta2']) < 0
    assert float(jump['to_theta1']) > 0 and float(jump['to_theta2']) > 0
    assert h.jumps[0].level == DiagnosticStatus.WARN
    assert t1 > 0 and t2 > 0                          # landed on the upper branch
    h.spin_until(lambda: h.warnings('branch_point at rho=0.155'), what='a WARN log line')
    v = h.wait_status(lambda v: v['jumps_total'] == '1' and float(v['rho']) == 0.1)
    assert v['last_jump_kind'] == 'branch_point'
    assert h.equilibrium[-1].level == DiagnosticStatus.OK     # the upper branch is stiff
    assert float(v['last_jump_rho']) == float(jump['rho'])

    # back up: the mechanism stays on the upper branch (hysteresis), no further jump
    rho, t1, t2, _ = h.command_rho(0.5)
    assert t1 > 0 and t2 > 0
    n = len(h.joint_states)
    h.spin_until(lambda: len(h.joint_states) > n + 3, what='more joint_states')
    assert len(h.jumps) == 1


def test_fig8a_fold_when_rising_on_the_lower_branch(harness):
    h = harness(fig8a_overrides()).ready()
    expected = _core_jumps(0.5, [-1.0, -1.0], 1.2, f3y=5.0, f4y=5.0)
    assert [j.kind for j in expected] == ['fold']
    _, t1, t2, _ = h.command_rho(1.2)
    h.spin_until(lambda: h.jumps, what='a jumps message')
    jump = values(h.jumps[0])
    assert jump['kind'] == 'fold'
    assert float(jump['rho']) == pytest.approx(float(expected[0].params.rho), abs=1e-9)
    assert 0.8 < float(jump['rho']) < 0.95            # C2 of fig. 8a (about 0.87)
    assert t1 > 0 and t2 > 0


def test_equilibrium_publishes_the_operation_range_and_warns_before_a_jump(harness):
    """The live branch's operation range is in ``equilibrium``, exact (C1, C2 of fig. 8a),
    and a command beyond it is warned about (and counted) before the jump happens."""
    h = harness(fig8a_overrides()).ready()
    v = h.wait_status(lambda v: v.get('rho_stable_min', 'none') != 'none')
    assert float(v['rho_stable_min']) == pytest.approx(0.1551013762561726, abs=1e-9)
    assert float(v['rho_stable_max']) == pytest.approx(0.8745334419192281, abs=1e-9)
    assert (v['rho_stable_min_end'], v['rho_stable_max_end']) == ('branch_point', 'fold')
    h.command_rho(0.3)                         # inside the range: no warning
    h.spin_until(lambda: h.counter('jump_warnings') == 0, what='diagnostics')
    h.command_rho(1.2)                         # beyond C2: warned, then the fold jump
    h.spin_until(lambda: h.warnings('leaves the stable branch at rho=0.874533'),
                 what='a WARN line before the jump')
    h.spin_until(lambda: h.jumps, what='the jump')
    h.spin_until(lambda: h.counter('jump_warnings') == 1, what='the warning counted')
    # on the upper branch now: its range has no end in (0, 2 (L1 + L2)) above
    v = h.wait_status(lambda v: float(v['rho']) == 1.2)
    assert v['rho_stable_max_end'] == 'limit'


def test_small_steps_cross_the_branch_point_too(harness):
    """A stream of small commands (a robot stack) finds the same jump as one big command."""
    h = harness(fig8a_overrides()).ready()
    expected = _core_jumps(0.5, [-1.0, -1.0], 0.1, f3y=5.0, f4y=5.0)[0]
    targets = [round(0.5 - 0.02 * i, 10) for i in range(1, 21)]     # 0.48 ... 0.10
    for rho in targets:
        h.rho_pub.publish(Float64(data=rho))
    # jumps and joint_states are two topics: wait for both (the jump may come with the
    # last command, when the earlier ones were coalesced)
    h.spin_until(lambda: h.joint_states[-1].position[0] == targets[-1] and h.jumps,
                 what='rho 0.1 and the jump')
    assert len(h.jumps) == 1
    jump = values(h.jumps[0])
    assert jump['kind'] == 'branch_point'
    assert float(jump['rho']) == pytest.approx(float(expected.params.rho), abs=1e-7)
    assert h.state()[1] > 0


# ---------------------------------------------------------------------------
# Bad input: dropped, counted in /diagnostics, state unchanged


BAD_RHO = [('non_finite', float('nan')), ('non_finite', float('inf')),
           ('non_finite', float('-inf')), ('out_of_range', 0.01), ('out_of_range', 2.5),
           ('out_of_range', -1.0)]


def test_bad_rho_commands_are_dropped_and_counted(harness):
    h = harness().ready()
    h.command_rho(0.8)
    h.spin_until(lambda: h.counter('rejected_total') is not None, what='/diagnostics')
    total = h.counter('rejected_total')
    for reason, value in BAD_RHO:
        total_now = h.rejected(f'rejected_{reason}',
                               lambda: h.rho_pub.publish(Float64(data=value)))
        assert total_now == total + 1
        total = total_now
    assert h.node.module_state()[0].rho == 0.8
    assert h.command_rho(0.85)[0] == 0.85               # still alive and obeying
    h.spin_until(lambda: h.warnings('rejected_out_of_range'), what='a warning')


def test_rejection_warnings_are_throttled(harness):
    h = harness().ready()
    h.spin_until(lambda: h.counter('rejected_non_finite') == 0, what='/diagnostics')
    for _ in range(5):
        h.rho_pub.publish(Float64(data=float('nan')))
    h.spin_until(lambda: h.counter('rejected_non_finite') == 5, what='5 rejections counted')
    h.spin_until(lambda: h.warnings('rejected_non_finite'), what='the warning')
    assert len(h.warnings('rejected_non_finite')) < 5


BAD_JOINT_COMMANDS = [
    ('size_mismatch', JointState(name=['m0_rho'], position=[0.5, 0.6])),
    ('size_mismatch', JointState(name=['m0_rho'], position=[])),
    ('size_mismatch', JointState()),
    ('unknown_joint', JointState(name=['m1_rho'], position=[0.5])),
    ('unknown_joint', JointState(name=['m0_theta1'], position=[0.5])),
    ('unknown_joint', JointState(name=['m0_rho', 'elbow'], position=[0.5, 0.5])),
    ('duplicate_joint', JointState(name=['m0_rho', 'm0_rho'], position=[0.5, 0.6])),
    ('non_finite', JointState(name=['m0_rho'], position=[float('nan')])),
    ('out_of_range', JointState(name=['m0_rho'], position=[3.0])),
]


def test_bad_joint_commands_are_dropped_and_counted(harness):
    h = harness().ready()
    # each twice (reversed: the same names back to back): the node keeps what it read
    # of the last names, a repeat must be refused and counted again
    for reason, msg in BAD_JOINT_COMMANDS + BAD_JOINT_COMMANDS[::-1]:
        h.rejected(f'rejected_{reason}', lambda: h.jc_pub.publish(msg))
    assert h.node.module_state()[0].rho == 0.75
    h.jc_pub.publish(JointState(name=['m0_rho'], position=[0.6]))    # now a good one
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.6, what='rho 0.6')


def test_bad_forces_are_dropped_and_counted(harness):
    h = harness().ready()
    for x, y in ((float('nan'), 0.0), (0.0, float('inf')), (float('-inf'), float('nan'))):
        for which in ('a3', 'a4'):
            h.rejected('rejected_non_finite',
                       lambda: h.force_pubs[which].publish(Vector3(x=x, y=y, z=0.0)))
    for which in ('a3', 'a4'):                          # beyond the supported 1e50 N
        h.rejected('rejected_out_of_range',
                   lambda: h.force_pubs[which].publish(Vector3(x=0.0, y=-1e60, z=0.0)))
    v = h.eq()
    assert (v['f3x'], v['f3y'], v['f4x'], v['f4y']) == ('0', '0', '0', '0')
    assert h.counter('callback_exceptions') == 0


def test_unexpected_exception_in_a_callback_is_counted_not_raised(harness, monkeypatch):
    # the tracker is injected where the node's simulator calls it
    import tensegrity_ros.core.simulation.mechanisms as node_module
    h = harness().ready()

    def broken(*args, **kwargs):
        raise RuntimeError('injected failure')

    monkeypatch.setattr(node_module, 'track_module', broken)
    h.spin_until(lambda: h.counter('callback_exceptions') is not None, what='/diagnostics')
    before = h.node.module_state()
    h.rho_pub.publish(Float64(data=0.9))
    h.spin_until(lambda: h.counter('callback_exceptions') == 1, what='exception counted')
    assert h.node.module_state() == before
    status = next(s for s in h.diagnostics[-1].status if s.name.endswith(': node'))
    assert status.level == DiagnosticStatus.ERROR
    monkeypatch.undo()
    assert h.command_rho(0.9)[0] == 0.9


def test_tracking_failure_keeps_the_last_verified_state(harness, monkeypatch):
    """If the tracker stops early, the node holds where it stopped (verified) and warns."""
    import dataclasses

    # the tracker is injected where the node's simulator calls it
    import tensegrity_ros.core.simulation.mechanisms as node_module
    real = node_module.track_module

    def stops_halfway(start, end, theta, **options):
        middle = start.with_(rho=0.5 * (start.rho + end.rho))
        track = real(start, middle, theta, **options)
        return dataclasses.replace(track, status='failed', message='injected stop')

    h = harness().ready()
    monkeypatch.setattr(node_module, 'track_module', stops_halfway)
    rho, t1, _, _ = h.command_rho(0.95, expect=0.85)
    assert t1 == pytest.approx(math.acos(0.85), abs=1e-8)
    v = h.wait_status(lambda v: 'injected stop' in v['tracking'])
    assert h.equilibrium[-1].level == DiagnosticStatus.WARN
    assert float(v['rho']) == 0.85
    h.spin_until(lambda: h.counter('tracking_failures') == 1, what='failure counted')
    monkeypatch.undo()
    assert h.command_rho(0.9)[0] == 0.9
    h.wait_status(lambda v: v['tracking'] == 'ok')
    assert h.equilibrium[-1].level == DiagnosticStatus.OK


def test_diagnostics_lists_every_counter(harness):
    h = harness().ready()
    h.spin_until(lambda: h.diagnostics, what='/diagnostics')
    statuses = h.diagnostics[-1].status
    node_status = next(s for s in statuses if s.name.endswith(': node'))
    keys = set(values(node_status))
    for reason in ('non_finite', 'out_of_range', 'size_mismatch', 'unknown_joint',
                   'duplicate_joint', 'parameter_type', 'parameter_read_only',
                   'parameter_undeclared', 'parameter_value'):
        assert f'rejected_{reason}' in keys
    assert {'rejected_total', 'commands_processed', 'callback_exceptions',
            'tracking_failures', 'jumps_total'} <= keys
    module_status = next(s for s in statuses if s.name.endswith(': m0'))
    assert values(module_status)['module'] == 'm0'


# ---------------------------------------------------------------------------
# Parameters: refusal with a reason, tracking of physical changes


def test_parameter_refusals_have_reasons_and_are_counted(harness):
    h = harness().ready()
    node = h.node
    before = node.module_state()
    refused = [
        (Parameter('m0.L1', value=-1.0), 'L1', 'rejected_parameter_value'),
        (Parameter('m0.k', value=0.0), 'k', 'rejected_parameter_value'),
        (Parameter('m0.kc', value=-5.0), 'kc', 'rejected_parameter_value'),
        (Parameter('m0.L2', value=float('nan')), 'L2', 'rejected_parameter_value'),
        (Parameter('m0.L1', value=1e99), 'L1', 'rejected_parameter_value'),     # overflows
        (Parameter('m0.force_a4', value=[0.0, -1e60]), 'f4y', 'rejected_parameter_value'),
        (Parameter('m0.force_a3', value=[1.0, 2.0, 3.0]), 'force_a3', 'rejected_parameter_value'),
        (Parameter('m0.force_a4', value=[float('inf'), 0.0]), 'force_a4',
         'rejected_parameter_value'),
        (Parameter('m0.rho_min', value=0.8), 'rho_initial', 'rejected_parameter_value'),
        (Parameter('m0.rho_max', value=0.01), 'rho_max', 'rejected_parameter_value'),
        (Parameter('m0.rho_initial', value=3.0), 'rho_initial', 'rejected_parameter_value'),
        (Parameter('m0.max_rho_rate', value=-1.0), 'out of range', 'rejected_parameter_value'),
        (Parameter('publish_rate', value=0.0), 'out of range', 'rejected_parameter_value'),
        (Parameter('frame_id', value=''), 'frame_id', 'rejected_parameter_value'),
        (Parameter('m0.L1', value='long'), 'type', 'rejected_parameter_type'),
        (Parameter('m0.force_a3', value=True), 'type', 'rejected_parameter_type'),
        (Parameter('modules', value=['m0', 'm1']), 'read-only', 'rejected_parameter_read_only'),
    ]
    for param, words, key in refused:
        count = node.counters[key]
        result = node.set_parameters([param])[0]
        assert not result.successful, param.name
        assert words in result.reason, (param.name, result.reason)
        assert node.counters[key] == count + 1, (param.name, key)
        assert node.module_state() == before
    # limits that would leave the actuator outside are refused as a whole
    count = node.counters['rejected_parameter_value']
    result = node.set_parameters_atomically([Parameter('m0.rho_min', value=0.8),
                                             Parameter('m0.rho_initial', value=0.9)])
    assert not result.successful and 'actuator is at rho=0.75' in result.reason
    assert node.counters['rejected_parameter_value'] == count + 1
    assert node.get_parameter('m0.rho_min').value == 0.05
    assert node.get_parameter('m0.L1').value == 1.0
    # the counts reach /diagnostics
    h.spin_until(lambda: h.counter('rejected_parameter_type') == 2, what='counts published')


def test_parameter_set_through_the_parameter_service(harness):
    """As `ros2 param set`: a refused value comes back with its reason; ints are accepted."""
    h = harness().ready()
    h.spin_until(h.params.services_are_ready, what='parameter services')
    result = h.call(h.params.set_parameters([Parameter('m0.L1', value='abc')]), 'set L1')
    assert not result.results[0].successful
    assert 'type' in result.results[0].reason
    result = h.call(h.params.set_parameters([Parameter('m0.k', value=-1.0)]), 'set k')
    assert not result.results[0].successful and 'k must be' in result.results[0].reason
    result = h.call(h.params.set_parameters([Parameter('m0.k', value=200)]), 'set k int')
    assert result.results[0].successful, result.results[0].reason
    assert h.node.get_parameter('m0.k').value == 200.0
    v = h.wait_status(lambda v: float(v['kc']) == 200.0)
    assert float(v['ka']) == 200.0
    desc = h.call(h.params.describe_parameters(['m0.max_rho_rate', 'modules']), 'describe')
    rate, modules = desc.descriptors
    assert rate.type == ParameterType.PARAMETER_DOUBLE and rate.description
    assert rate.floating_point_range[0].from_value == 0.0
    assert modules.read_only


def test_stiffness_override_convention(harness):
    h = harness({'m0.k': 100.0, 'm0.kc': 50.0}).ready()
    params, _ = h.node.module_state()
    assert (params.ka, params.kb, params.kc) == (100.0, 100.0, 50.0)
    assert h.node.set_parameters([Parameter('m0.k', value=80.0)])[0].successful
    params, _ = h.node.module_state()
    assert (params.ka, params.kb, params.kc) == (80.0, 80.0, 50.0)
    assert h.node.set_parameters([Parameter('m0.kc', value=0.0)])[0].successful
    assert h.node.module_state()[0].kc == 80.0


def test_runtime_force_parameters_are_tracked_with_jumps(harness):
    """Lower branch at rho = 0.75 unloaded; pulling 20 N up at A3 and A4: a fold on the way."""
    h = harness({'m0.initial_theta': [-0.7, -0.7]}).ready()
    start, eq0 = h.node.module_state()
    end = start.with_(f3y=20.0, f4y=20.0)
    expected = track_module(start, end, eq0.theta)
    assert [j.kind for j in expected.jumps] == ['fold']
    result = h.node.set_parameters_atomically([Parameter('m0.force_a3', value=[0.0, 20.0]),
                                               Parameter('m0.force_a4', value=[0.0, 20.0])])
    assert result.successful, result.reason
    h.spin_until(lambda: h.jumps, what='a jumps message')
    jump = values(h.jumps[0])
    assert jump['kind'] == 'fold' and float(jump['rho']) == 0.75
    assert float(jump['f3y']) == pytest.approx(float(expected.jumps[0].params.f3y), abs=1e-9)
    assert 'parameter' in jump['cause']
    v = h.wait_status(lambda v: float(v['f3y']) == 20.0)
    assert float(v['theta1']) == pytest.approx(expected.final.theta1, abs=1e-9)
    assert float(v['theta1']) > 0
    h.spin_until(lambda: h.state()[1] > 0, what='joint_states on the upper branch')


def test_runtime_geometry_change_is_tracked(harness):
    h = harness().ready()
    start, eq0 = h.node.module_state()
    assert h.node.set_parameters([Parameter('m0.L2', value=1.05)])[0].successful
    expected = track_module(start, start.with_(L2=1.05), eq0.theta)
    v = h.wait_status(lambda v: float(v['L2']) == 1.05)
    assert float(v['theta2']) == pytest.approx(expected.final.theta2, abs=1e-9)


# ---------------------------------------------------------------------------
# Reset, speed limit, markers, QoS


def test_reset_returns_to_the_initial_state(harness):
    h = harness(fig8a_overrides()).ready()
    initial = h.state()
    h.command_rho(0.1)
    h.spin_until(lambda: h.jumps, what='jump')
    h.force_pubs['a3'].publish(Vector3(x=0.0, y=1.0, z=0.0))
    h.wait_status(lambda v: float(v['f3y']) == 1.0)
    h.spin_until(h.reset_client.service_is_ready, what='reset service')
    response = h.call(h.reset_client.call_async(Trigger.Request()), 'reset')
    assert response.success, response.message
    assert 'm0' in response.message
    # the actuator and the branch are reset; the loads are the live ones (the force
    # parameters read them back): fig. 8a's lower branch under f3y = 1
    v = h.wait_status(lambda v: v['jumps_total'] == '0')
    assert float(v['f3y']) == 1.0 and float(v['f4y']) == 5.0 and float(v['rho']) == 0.5
    assert float(v['theta1']) < 0
    expected = settle(ModuleParams.paper(0.5, F3=1.0, F4=5.0), [-1.0, -1.0])
    h.spin_until(lambda: h.state()[1:3] == pytest.approx(tuple(expected.theta), abs=1e-9),
                 what='the reset state under the live loads')
    # the loads back as they were: the very initial state
    h.force_pubs['a3'].publish(Vector3(x=0.0, y=5.0, z=0.0))
    h.wait_status(lambda v: float(v['f3y']) == 5.0)
    response = h.call(h.reset_client.call_async(Trigger.Request()), 'reset')
    assert response.success, response.message
    h.spin_until(lambda: h.state() == initial, what='initial joint_states')


def test_speed_limit_splits_a_command_into_segments(harness):
    rate = 0.5
    h = harness({'m0.max_rho_rate': rate, 'publish_rate': 50.0}).ready()
    n = len(h.joint_states)
    h.rho_pub.publish(Float64(data=0.95))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.95, what='rho reaches 0.95')
    moving = list(h.joint_states[n:])
    rhos = [m.position[0] for m in moving]
    assert rhos == sorted(rhos)                                # monotone
    intermediate = [r for r in rhos if 0.75 < r < 0.95]
    assert len(intermediate) >= 5                              # many segments, not one jump
    t0 = moving[0].header.stamp.sec
    stamps = [(m.header.stamp.sec - t0) + 1e-9 * m.header.stamp.nanosec for m in moving]
    for (r0, s0), (r1, s1) in zip(zip(rhos, stamps), zip(rhos[1:], stamps[1:])):
        assert r1 - r0 <= rate * (s1 - s0) + 1e-9             # never faster than the limit
    first_moving = next(i for i, r in enumerate(rhos) if r > 0.75)
    last_before = first_moving - 1 if first_moving > 0 else 0
    assert stamps[-1] - stamps[last_before] >= 0.2 / rate * 0.9
    # a new command retargets the motion from where the actuator is
    h.rho_pub.publish(Float64(data=0.9))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.9, what='rho back to 0.9')
    # 0 = no limit: one path per command
    assert h.node.set_parameters([Parameter('m0.max_rho_rate', value=0.0)])[0].successful
    assert h.command_rho(0.7)[0] == 0.7


def test_markers_draw_rods_springs_nodes(harness):
    h = harness({'frame_id': 'neck_base'}).ready()
    h.spin_until(lambda: h.markers, what='markers')
    markers = {m.id: m for m in h.markers[-1].markers}
    assert {m.type for m in markers.values()} == {Marker.LINE_LIST, Marker.SPHERE_LIST}
    assert all(m.header.frame_id == 'neck_base' and m.ns == 'm0' for m in markers.values())
    rods, springs, nodes = markers[0], markers[2], markers[3]
    assert len(rods.points) == 4 and len(springs.points) == 6 and len(nodes.points) == 4
    _, eq = h.node.module_state()
    a3 = nodes.points[2]
    assert (a3.x, a3.y) == pytest.approx((math.cos(eq.theta1), math.sin(eq.theta1)))
    assert rods.color.g > rods.color.r                       # green: stable, far from a jump


def test_near_a_jump_the_status_warns(harness):
    # just above C1 on the lower branch the stability margin is small
    h = harness(fig8a_overrides(**{'m0.rho_initial': 0.16})).ready()
    assert h.equilibrium[-1].level == DiagnosticStatus.WARN
    assert 'near a jump' in h.equilibrium[-1].message
    h.spin_until(lambda: h.markers, what='markers')
    assert h.markers[-1].markers[0].color.r > h.markers[-1].markers[0].color.g


def test_qos_contract(harness):
    from tensegrity_ros.ros import qos as node_qos
    h = harness().ready()
    node = h.node
    ns = h.ns

    def pub_qos(topic):
        return node.get_publishers_info_by_topic(topic)[0].qos_profile

    def sub_qos(topic):
        info = [i for i in node.get_subscriptions_info_by_topic(topic)
                if i.node_name == node.get_name()]
        return info[0].qos_profile

    for topic in ('stable', 'equilibrium', 'motion', 'head_pose', 'markers'):
        q = pub_qos(h.private(topic))
        assert q.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert q.reliability == ReliabilityPolicy.RELIABLE
    assert node_qos.STATUS_QOS.depth == 1 and node_qos.COMMAND_QOS.depth >= 10
    assert pub_qos(h.private('jumps')).durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert pub_qos(f'{ns}/joint_states').durability == DurabilityPolicy.VOLATILE
    assert node.get_publishers_info_by_topic('/diagnostics')
    for topic in ('m0/rho_cmd', 'm0/force_a3', 'm0/force_a4', 'joint_commands',
                  'joint_trajectory'):
        q = sub_qos(f'{ns}/{topic}')
        assert q.reliability == ReliabilityPolicy.RELIABLE
        assert q.durability == DurabilityPolicy.VOLATILE


# ---------------------------------------------------------------------------
# Configuration errors


def test_more_than_max_modules_is_refused_at_startup(ros):
    names = [f'm{i}' for i in range(21)]
    with pytest.raises(ConfigurationError, match='21 modules given; a node hosts 1 to 20'):
        TensegrityNode(parameter_overrides=[Parameter('modules', value=names)])
    with pytest.raises(ConfigurationError, match='distinct'):
        TensegrityNode(parameter_overrides=[Parameter('modules', value=['m0', 'm0'])])


@pytest.mark.parametrize('overrides, words', [
    ({'m0.rho_initial': 5.0}, 'rho_initial'),
    ({'m0.L1': -1.0}, 'L1'),
    ({'m0.force_a3': [1.0]}, 'force_a3'),
    ({'m0.L1': 'one'}, 'm0.L1'),
    ({'modules': ['0bad']}, 'module name'),
    ({'publish_rate': 0.0}, 'publish_rate'),
])
def test_bad_configuration_is_refused_at_startup(ros, overrides, words):
    with pytest.raises(ConfigurationError, match=words):
        TensegrityNode(parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])


def test_integer_config_values_are_taken_as_doubles(harness):
    h = harness({'m0.L1': 1, 'm0.force_a3': [0, 2]}).ready()
    params, _ = h.node.module_state()
    assert params.L1 == 1.0 and params.f3y == 2.0
