"""What a robot stack adopting the node relies on (issue 33), driven as a client would.

Private names; parameters that read back the live loads and refuse what the node would not
honour (rates above publish_rate, frame ids TF refuses, deletes); the TF chain on /tf (or,
without tf2_msgs, one INFO line and none); the JointTrajectory input and its ~/motion
status.  References: the core's own trajectory and frame chain are tested without ROS
(test_trajectory.py, test_frames.py); here the node must pass them through unchanged: fig.
8a's jump on a trajectory lands where the tracker lands, /tf composes to head_pose.

Every test makes its own node in its own namespace (the harness), so they run in any order
and in parallel workers.
"""
import math

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, Vector3
import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from tensegrity_ros.core import ModuleParams, settle, track_module
from test_node import fig8a_overrides, LATCHED_QOS, PUB_QOS, values

pytestmark = pytest.mark.ros


def trajectory_msg(points, joints=('m0_rho',)):
    """points: (seconds, [positions]) ..."""
    msg = JointTrajectory(joint_names=list(joints))
    for t, positions in points:
        sec = math.floor(t)
        msg.points.append(JointTrajectoryPoint(
            positions=[float(p) for p in positions],
            time_from_start=Duration(sec=int(sec), nanosec=int(round((t - sec) * 1e9)))))
    return msg


class Motion:
    """A harness with a joint_trajectory publisher and the latched ~/motion status."""

    def __init__(self, h):
        self.h = h
        self.pub = h.client.create_publisher(JointTrajectory, 'joint_trajectory', PUB_QOS)
        self.status = []
        h.client.create_subscription(DiagnosticStatus, h.private('motion'), self.status.append,
                                     LATCHED_QOS)
        h.spin_until(lambda: self.pub.get_subscription_count() > 0 and self.status,
                     what='joint_trajectory discovery and ~/motion')

    def last(self):
        return values(self.status[-1])

    def wait(self, state, id_):
        self.h.spin_until(lambda: self.status and self.last()['state'] == state
                          and self.last()['id'] == str(id_), what=f'~/motion {state} {id_}')
        return self.status[-1]


# ---------------------------------------------------------------------------
# names


def test_the_nodes_own_outputs_and_service_are_private(harness):
    h = harness().ready()
    node = h.node
    mine = dict(node.get_publisher_names_and_types_by_node(node.get_name(), h.ns))
    for name in ('stable', 'equilibrium', 'jumps', 'markers', 'head_pose', 'motion'):
        assert h.private(name) in mine, (name, sorted(mine))
        assert f'{h.ns}/{name}' not in mine
    assert f'{h.ns}/joint_states' in mine and '/diagnostics' in mine
    services = dict(node.get_service_names_and_types_by_node(node.get_name(), h.ns))
    assert services[h.private('reset')] == ['std_srvs/srv/Trigger']
    assert f'{h.ns}/reset' not in services
    subscribed = dict(node.get_subscriber_names_and_types_by_node(node.get_name(), h.ns))
    for name in ('m0/rho_cmd', 'm0/force_a3', 'm0/force_a4', 'joint_commands',
                 'joint_trajectory'):
        assert f'{h.ns}/{name}' in subscribed, name
    assert subscribed[f'{h.ns}/joint_trajectory'] == ['trajectory_msgs/msg/JointTrajectory']


# ---------------------------------------------------------------------------
# parameters


def test_force_parameters_read_back_the_live_loads_whatever_set_them(harness):
    h = harness().ready()
    h.spin_until(h.params.services_are_ready, what='parameter services')

    def remote(name):
        result = h.call(h.params.get_parameters([name]), f'get {name}')
        return list(result.values[0].double_array_value)

    assert remote('m0.force_a4') == [0.0, 0.0]
    h.force_pubs['a4'].publish(Vector3(x=0.5, y=-2.0, z=7.0))        # z is ignored
    h.wait_status(lambda v: float(v['f4y']) == -2.0)
    assert list(h.node.get_parameter('m0.force_a4').value) == [0.5, -2.0]
    assert remote('m0.force_a4') == [0.5, -2.0]
    assert remote('m0.force_a3') == [0.0, 0.0]
    # a parameter set is live too, and a later message overrides it again
    result = h.call(h.params.set_parameters([Parameter('m0.force_a3', value=[0.0, 1.0])]),
                    'set force_a3')
    assert result.results[0].successful
    h.wait_status(lambda v: float(v['f3y']) == 1.0)
    h.force_pubs['a3'].publish(Vector3(x=0.0, y=3.0, z=0.0))
    h.wait_status(lambda v: float(v['f3y']) == 3.0)
    assert remote('m0.force_a3') == [0.0, 3.0]
    assert h.node.counters['rejected_parameter_value'] == 0


def test_rates_above_publish_rate_are_refused_as_they_would_not_be_honoured(harness):
    h = harness({'publish_rate': 20.0, 'markers_rate': 10.0, 'diagnostics_rate': 1.0}).ready()
    node = h.node
    for param, other in ((Parameter('markers_rate', value=40.0), 'publish_rate=20.0'),
                         (Parameter('diagnostics_rate', value=25.0), 'publish_rate=20.0'),
                         (Parameter('publish_rate', value=5.0), 'markers_rate=10.0')):
        count = node.counters['rejected_parameter_value']
        result = node.set_parameters([param])[0]
        assert not result.successful and other in result.reason, result.reason
        assert 'publish_rate timer' in result.reason
        assert node.counters['rejected_parameter_value'] == count + 1
    assert node.get_parameter('markers_rate').value == 10.0
    # both at once: applied, and honoured (markers at 40 Hz need ticks at 40 Hz at least)
    result = node.set_parameters_atomically([Parameter('publish_rate', value=100.0),
                                             Parameter('markers_rate', value=40.0)])
    assert result.successful, result.reason
    assert node.get_parameter('markers_rate').value == 40.0


def test_a_start_up_rate_above_publish_rate_is_a_configuration_error(ros):
    from tensegrity_ros.ros.node import ConfigurationError, TensegrityNode
    with pytest.raises(ConfigurationError, match='markers_rate=60.0 above publish_rate=50.0'):
        TensegrityNode(namespace='/rates_at_startup',
                       parameter_overrides=[Parameter('markers_rate', value=60.0)])


@pytest.mark.parametrize('frame, words', [
    ('bad frame/with spaces', 'not a TF frame id'),
    ('/tensegrity_base', 'no leading /'),
    ('a//b', 'not a TF frame id'),
    ('base/', 'not a TF frame id'),
    ('', 'must not be empty'),
])
def test_frame_id_must_be_a_tf_frame_id(harness, frame, words):
    h = harness().ready()
    count = h.node.counters['rejected_parameter_value']
    result = h.node.set_parameters([Parameter('frame_id', value=frame)])[0]
    assert not result.successful and words in result.reason, result.reason
    assert h.node.counters['rejected_parameter_value'] == count + 1
    assert h.node.get_parameter('frame_id').value == 'tensegrity_base'


def test_frame_prefix_names_every_frame(harness):
    h = harness({'frame_prefix': 'robot1/', 'frame_id': 'neck_base'}).ready()
    h.spin_until(lambda: h.markers, what='markers')
    assert {m.header.frame_id for m in h.markers[-1].markers} == {'robot1/neck_base'}
    result = h.node.set_parameters([Parameter('frame_prefix', value='bad prefix ')])[0]
    assert not result.successful and 'frame_prefix + frame_id' in result.reason


def test_parameter_delete_is_refused_with_its_own_reason_and_counter(harness):
    h = harness().ready()
    h.spin_until(h.params.services_are_ready, what='parameter services')
    node = h.node
    before = dict(node.counters)
    # what `ros2 param delete /ns/tensegrity m0.L1` sends
    result = h.call(h.params.delete_parameters(['m0.L1']), 'delete m0.L1')
    assert not result.results[0].successful
    assert 'cannot be undeclared' in result.results[0].reason
    assert node.counters['rejected_parameter_delete'] == before['rejected_parameter_delete'] + 1
    assert node.counters['rejected_parameter_type'] == before['rejected_parameter_type']
    assert node.get_parameter('m0.L1').value == 1.0
    h.spin_until(lambda: any('cannot be deleted' in m.msg for m in h.log), what='the warning')


# ---------------------------------------------------------------------------
# TF


def test_without_tf2_msgs_one_info_line_and_no_tf(harness, monkeypatch):
    import tensegrity_ros.ros.node as node_module
    monkeypatch.setattr(node_module, 'TFMessage', None)
    h = harness().ready()
    assert '/tf' not in dict(h.node.get_publisher_names_and_types_by_node(
        h.node.get_name(), h.ns))
    # said at start-up, before this client subscribed: /rosout keeps it (transient local)
    log = []
    h.client.create_subscription(
        Log, '/rosout', lambda m: log.append(m) if m.name == h.node.get_logger().name else None,
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    h.spin_until(lambda: any('tf2_msgs is not installed' in m.msg for m in log),
                 what='the INFO line')
    lines = [m for m in log if 'tf2_msgs' in m.msg]
    assert len(lines) == 1 and lines[0].level == Log.INFO


def test_tf_chain_composes_to_the_head_pose(harness):
    pytest.importorskip('tf2_msgs', reason='no tf2_msgs wheel on PyPI: this test runs where '
                        'ROS has it (colcon test in a ROS environment, docs/development.md)')
    from tf2_msgs.msg import TFMessage

    from test_node_neck import NECK_CONFIG
    h = harness(cli_args=['--ros-args', '--params-file', str(NECK_CONFIG)],
                parameters={'frame_prefix': 'bird/'}).ready()
    tf, head = [], []
    h.client.create_subscription(TFMessage, '/tf', tf.append, 100)
    h.client.create_subscription(PoseStamped, h.private('head_pose'), head.append, LATCHED_QOS)
    chain = ['bird/tensegrity_base', 'bird/m0_top_chord', 'bird/m1_top_chord',
             'bird/m2_top_chord', 'bird/head']

    def ours(msg):
        return [t for t in msg.transforms if t.child_frame_id.startswith('bird/')]
    h.spin_until(lambda: head and any(len(ours(m)) == 4 for m in tf), what='/tf and head_pose')
    transforms = next(ours(m) for m in reversed(tf) if len(ours(m)) == 4)
    assert [(t.header.frame_id, t.child_frame_id) for t in transforms] == list(
        zip(chain, chain[1:]))
    pose = np.eye(3)
    for t in transforms:
        yaw = 2 * math.atan2(t.transform.rotation.z, t.transform.rotation.w)
        c, s = math.cos(yaw), math.sin(yaw)
        pose = pose @ np.array([[c, -s, t.transform.translation.x],
                                [s, c, t.transform.translation.y], [0, 0, 1]])
    p = head[-1].pose
    assert pose[0, 2] == pytest.approx(p.position.x, abs=1e-12)
    assert pose[1, 2] == pytest.approx(p.position.y, abs=1e-12)
    assert math.atan2(pose[1, 0], pose[0, 0]) == pytest.approx(
        2 * math.atan2(p.orientation.z, p.orientation.w), abs=1e-12)


# ---------------------------------------------------------------------------
# joint_trajectory


def test_a_trajectory_is_tracked_its_jump_reported_and_its_end_latched(harness):
    """Fig. 8a: 0.5 -> 0.1 in 0.4 s from the lower branch crosses the branch point C1; the
    jump comes on ~/jumps with the trajectory as its cause; ~/motion goes from executing
    to succeeded; the state is the tracker's end of the same straight path."""
    h = harness(fig8a_overrides()).ready()
    motion = Motion(h)
    assert motion.last()['state'] == 'idle'
    motion.pub.publish(trajectory_msg([(0.2, [0.3]), (0.4, [0.1])]))
    motion.wait('executing', 1)
    done = motion.wait('succeeded', 1)
    v = values(done)
    assert v['joints'] == '[m0_rho]' and v['goal'] == '[0.10000000000000001]'
    assert float(v['duration']) == pytest.approx(0.4) and v['points'] == '2'
    assert done.level == DiagnosticStatus.OK and 'reached m0 rho=0.1' in done.message
    h.spin_until(lambda: h.jumps, what='the jump')
    jump = values(h.jumps[-1])
    assert jump['kind'] == 'branch_point' and jump['cause'] == 'joint_trajectory'
    assert float(jump['rho']) == pytest.approx(0.155, abs=0.005)
    fig8a = ModuleParams.paper(0.5, F3=5.0, F4=5.0)
    expected = track_module(fig8a, fig8a.with_rho(0.1), settle(fig8a, [-1.0, -1.0]).theta)
    h.spin_until(lambda: h.state()[0] == 0.1, what='rho = 0.1 on joint_states')
    np.testing.assert_allclose(h.state()[1:3], expected.final.theta, atol=1e-6)
    assert h.node.counters['trajectories_accepted'] == 1
    assert h.node.counters['trajectories_succeeded'] == 1


def test_a_command_cancels_the_trajectory_of_its_module(harness):
    h = harness().ready()
    motion = Motion(h)
    motion.pub.publish(trajectory_msg([(30.0, [1.5])]))
    motion.wait('executing', 1)
    h.command_rho(0.6)
    done = motion.wait('canceled', 1)
    assert 'canceled by rho_cmd' in done.message
    assert h.node.counters['trajectories_canceled'] == 1


@pytest.mark.parametrize('msg, key, words', [
    (trajectory_msg([(1.0, [0.8])], joints=('m9_rho',)), 'rejected_unknown_joint', 'm9_rho'),
    (trajectory_msg([(1.0, [0.8, 0.9])], joints=('m0_rho', 'm0_rho')),
     'rejected_duplicate_joint', 'twice'),
    (trajectory_msg([(1.0, [0.8]), (1.0, [0.9])]), 'rejected_trajectory_time',
     'does not increase'),
    (trajectory_msg([(2.0, [0.8]), (1.0, [0.9])]), 'rejected_trajectory_time',
     'does not increase'),
    (trajectory_msg([(1.0, [math.nan])]), 'rejected_non_finite', 'not finite'),
    (trajectory_msg([(1.0, [0.8, 0.9])]), 'rejected_size_mismatch', '2 positions'),
    (trajectory_msg([(1.0, [5.0])]), 'rejected_out_of_range', 'outside'),
])
def test_bad_trajectories_are_refused_with_a_reason_and_counted(harness, msg, key, words):
    h = harness().ready()
    motion = Motion(h)
    h.rejected(key, lambda: motion.pub.publish(msg))
    h.spin_until(lambda: any(words in m for m in h.warnings('joint_trajectory')),
                 what=f'a warning saying {words!r}')
    assert motion.last()['state'] == 'idle'


# ---------------------------------------------------------------------------
# what the parameters read back (module_parameters.live_values, ROS-free)


def _getter(**values):
    from tensegrity_ros.module_parameters import MODULE_DEFAULTS
    table = dict(MODULE_DEFAULTS, **values)
    return lambda key: table[key]


def test_live_values_are_what_no_longer_reads_back():
    from tensegrity_ros.module_parameters import live_values
    live = ModuleParams.paper(0.5, F3=5.0, F4=5.0)
    assert live_values(_getter(force_a3=[0.0, 5.0], force_a4=[0.0, 5.0]), live) == {}
    assert live_values(_getter(), live) == {'force_a3': [0.0, 5.0], 'force_a4': [0.0, 5.0]}
    # springs following k (0.0) read back through k; an override through itself
    stopped = live.with_(ka=120.0, kb=120.0, kc=120.0, L1=1.1)
    got = live_values(_getter(k=150.0, force_a3=[0.0, 5.0], force_a4=[0.0, 5.0]), stopped)
    assert got == {'k': 120.0, 'L1': 1.1}
    got = live_values(_getter(kc=90.0, force_a3=[0.0, 5.0], force_a4=[0.0, 5.0]),
                      live.with_(kc=95.0))
    assert got == {'kc': 95.0}
    # springs following k that no longer agree: each reads back its own
    got = live_values(_getter(force_a3=[0.0, 5.0], force_a4=[0.0, 5.0]),
                      live.with_(ka=110.0))
    assert got == {'ka': 110.0, 'kb': 100.0, 'kc': 100.0}


def test_dynamics_mode_a_parameter_change_keeps_a_force_sent_during_the_motion(harness):
    """The rods move (dynamics mode); a force message, then a design change, both while
    they move: the change starts from the live design, so the message's load stays (it
    started from the last rest state and undid it before), and the parameter reads it."""
    from test_node_dynamics import dynamics_overrides
    h = harness(dynamics_overrides(**{'m0.rho_initial': 0.5, 'm0.max_rho_rate': 0.02})).ready()
    h.rho_pub.publish(h.rho_pub.msg_type(data=0.6))                  # 5 s of motion
    h.spin_until(lambda: not h.stable[-1].data, what='the rods moving')
    h.force_pubs['a3'].publish(Vector3(x=0.0, y=4.0, z=0.0))
    h.spin_until(lambda: list(h.node.get_parameter('m0.force_a3').value) == [0.0, 4.0],
                 what='force_a3 read back during the motion')
    result = h.node.set_parameters([Parameter('m0.L2', value=1.01)])[0]
    assert result.successful, result.reason
    assert h.node.simulator.moving
    h.spin_until(lambda: h.stable[-1].data, timeout=60, what='the rods at rest')
    v = h.wait_status(lambda v: float(v['rho']) == 0.6)
    assert float(v['f3y']) == 4.0 and float(v['L2']) == 1.01
    assert list(h.node.get_parameter('m0.force_a3').value) == [0.0, 4.0]
