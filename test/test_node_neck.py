"""The neck stack through the node: config/neck.yaml (three modules) driven by topics.

Uses the Harness of test_node.py (in-process node + client node, spun until a condition
holds; no sleeps).  The expected jumps are computed with the core (track_stack) first.
"""
import math

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, Vector3
import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from tensegrity_ros.core.neck.stack import settle_stack, track_stack
from tensegrity_ros.ros import commands
from test_node import LATCHED_QOS, PUB_QOS, ROOT, STREAM_QOS, values

pytestmark = pytest.mark.ros

NECK_CONFIG = ROOT / 'config' / 'neck.yaml'
MODULES = ('m0', 'm1', 'm2')
JOINTS = [f'{m}_{j}' for m in MODULES for j in ('rho', 'theta1', 'theta2')]


class Neck:
    """Harness helpers for the three-module neck."""

    def __init__(self, make, **kwargs):
        self.h = h = make(cli_args=['--ros-args', '--params-file', str(NECK_CONFIG)], **kwargs)
        c = h.client
        self.rho_pubs = {m: c.create_publisher(Float64, f'{m}/rho_cmd', PUB_QOS)
                         for m in MODULES}
        self.force_pubs = {(m, w): c.create_publisher(Vector3, f'{m}/force_{w}', PUB_QOS)
                           for m in MODULES for w in ('a3', 'a4')}
        self.head = []
        c.create_subscription(PoseStamped, h.private('head_pose'), self.head.append,
                              LATCHED_QOS)
        h.ready()
        pubs = [*self.rho_pubs.values(), *self.force_pubs.values()]
        h.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs) and self.head,
                     what='neck discovery and head_pose')

    def joints(self):
        msg = self.h.joint_states[-1]
        assert list(msg.name) == JOINTS
        return dict(zip(msg.name, msg.position)), dict(zip(msg.name, msg.effort))

    def wait_state(self, predicate, what):
        h = self.h
        n = len(h.joint_states)
        h.spin_until(lambda: len(h.joint_states) > n and predicate(self.joints()[0]), what=what)
        return self.joints()

    def load_head(self, per_node):
        """A vertical head load (N per head node, down) in one atomic parameter set: one
        symmetric path.  Returns the (stack, equilibrium) after it."""
        result = self.h.node.set_parameters_atomically(
            [Parameter(f'm2.force_{w}', value=[0.0, -per_node]) for w in ('a3', 'a4')])
        assert result.successful
        return self.h.node.stack_state()

    def statuses(self):
        """The last equilibrium status of every module."""
        last = {}
        for st in self.h.equilibrium:
            v = values(st)
            last[v['module']] = v
        return last


def _angles(v, side):
    return np.array([[float(v[f'{side}_{m}_theta1']), float(v[f'{side}_{m}_theta2'])]
                     for m in MODULES])


def test_neck_starts_upright_with_all_joints_and_head_pose(neck):
    n = neck()
    h = n.h
    stack, eq = h.node.stack_state()
    assert h.node.modules == list(MODULES) and len(stack) == 3 and eq.stable
    pos, effort = n.joints()
    assert [pos[f'{m}_rho'] for m in MODULES] == [0.09, 0.085, 0.08]
    for i, m in enumerate(MODULES):
        assert pos[f'{m}_theta1'] == eq.theta[i][0] and pos[f'{m}_theta2'] == eq.theta[i][1]
        assert effort[f'{m}_rho'] == eq.actuator_forces[i]
    # upright, symmetric: the head is level, centred over the base
    head = n.head[-1]
    assert head.header.frame_id == 'tensegrity_base'
    assert head.pose.position.x == pytest.approx(eq.head_position[0], abs=1e-12)
    assert head.pose.position.y == pytest.approx(eq.head_position[1], abs=1e-12)
    assert head.pose.position.x == pytest.approx(0.045, abs=1e-9)
    assert 2.0 * math.atan2(head.pose.orientation.z, head.pose.orientation.w) == \
        pytest.approx(eq.head_angle, abs=1e-12)
    # one equilibrium status per module, stability of the whole stack
    h.spin_until(lambda: set(n.statuses()) == set(MODULES), what='three statuses')
    for m, v in n.statuses().items():
        assert v['stable'] == 'true'
        assert float(v['stability_margin']) == pytest.approx(eq.stability_margin)
        assert v['num_equilibria'] == 'none' and v['rho_stable_min'] == 'none'
    h.spin_until(lambda: h.markers, what='markers')
    ns = {mk.ns for mk in h.markers[-1].markers}
    assert ns == set(MODULES)
    nodes = next(mk for mk in h.markers[-1].markers if mk.ns == 'm2' and mk.id == 3).points
    # m2's A1, A2 are m1's A4, A3 (stack node table: A3(1) = 4, A4(1) = 5)
    assert (nodes[0].x, nodes[0].y) == pytest.approx(tuple(eq.nodes[5]))
    assert (nodes[1].x, nodes[1].y) == pytest.approx(tuple(eq.nodes[4]))


def test_lower_module_command_moves_the_whole_neck(neck):
    n = neck()
    h = n.h
    stack0, eq0 = h.node.stack_state()
    n.rho_pubs['m1'].publish(Float64(data=0.09))
    pos, effort = n.wait_state(lambda p: p['m1_rho'] == 0.09, 'm1_rho = 0.09')
    stack, eq = h.node.stack_state()
    expected = track_stack(stack0, stack0.with_module(1, rho=0.09), eq0)
    assert not expected.jumps and eq.stable
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    assert pos['m0_rho'] == 0.09 and pos['m2_rho'] == 0.08
    for i, m in enumerate(MODULES):
        assert pos[f'{m}_theta1'] == eq.theta[i][0]
    assert not h.jumps
    # joint_commands: two actuators on one path
    h.jc_pub.publish(JointState(name=['m0_rho', 'm2_rho'], position=[0.1, 0.075]))
    pos, _ = n.wait_state(lambda p: p['m0_rho'] == 0.1 and p['m2_rho'] == 0.075,
                          'joint_commands state')
    assert pos['m1_rho'] == 0.09
    n.h.spin_until(lambda: n.head and n.head[-1].pose.position.y == pytest.approx(
        h.node.stack_state()[1].head_position[1], abs=1e-12), what='new head pose')


def test_head_load_jump_reported_by_a_lower_module_command(neck):
    n = neck()
    h = n.h
    # a heavy head (3.5 N per head node, below the ~3.9 N sideways buckling load) in one
    # parameter set = one path: no jump yet
    stack0, eq0 = h.node.stack_state()
    loaded = stack0.with_module(2, f3y=-3.5, f4y=-3.5)
    assert not track_stack(stack0, loaded, eq0).jumps
    result = h.node.set_parameters_atomically([Parameter('m2.force_a3', value=[0.0, -3.5]),
                                               Parameter('m2.force_a4', value=[0.0, -3.5])])
    assert result.successful
    stack, eq = h.node.stack_state()
    assert stack == loaded and eq.stable and not h.node.counters['jumps_total']
    # shortening m0 now buckles the neck sideways (continuously) and then snaps it over
    # at a fold of m0 (found with the core first)
    expected = track_stack(stack, stack.with_module(0, rho=0.05), eq)
    assert [j.kind for j in expected.jumps] == ['fold'] and len(expected.passages) == 1
    jump = expected.jumps[0]
    n.rho_pubs['m0'].publish(Float64(data=0.05))
    h.spin_until(lambda: h.jumps, what='a jump')
    msg = h.jumps[-1]
    assert msg.level == DiagnosticStatus.WARN
    v = values(msg)
    assert v['module'] == 'm0' and v['kind'] == 'fold' and v['cause'] == 'rho_cmd'
    assert float(v['rho']) == pytest.approx(jump.stack.modules[0].rho, abs=1e-9)
    assert 0.05 < float(v['rho']) < 0.09
    assert float(v['s']) == pytest.approx(jump.s, abs=1e-9)
    assert v['ambiguous'] == ('true' if jump.ambiguous else 'false')
    np.testing.assert_allclose(_angles(v, 'from'), jump.from_theta, atol=1e-9)
    np.testing.assert_allclose(_angles(v, 'to'), jump.to_theta, atol=1e-9)
    assert float(v['from_theta1']) == float(v['from_m0_theta1'])
    assert float(v['to_theta2']) == float(v['to_m0_theta2'])
    landing = (jump.landing_stack or jump.stack).modules       # where to_theta is a minimum
    assert float(v['landing_rho']) == pytest.approx(landing[0].rho, abs=1e-9)
    assert float(v['landing_m2_rho']) == pytest.approx(landing[2].rho, abs=1e-9)
    # the node lands where the core does; every module records the jump
    h.spin_until(lambda: h.node.stack_state()[0].modules[0].rho == 0.05, what='landing')
    np.testing.assert_allclose(h.node.stack_state()[1].theta, expected.final.theta, atol=1e-8)
    h.spin_until(lambda: all(v.get('last_jump_kind') == 'fold'
                             for v in n.statuses().values()), what='statuses with the jump')
    assert len(h.jumps) == 1 and h.node.counters['jumps_total'] == 1
    # reset returns to rho_initial (with the force parameters now set) and settles upright
    result = h.call(h.reset_client.call_async(Trigger.Request()), 'reset')
    assert result.success
    # a loaded neck's settle may take more than one call's time budget: it ends on ticks
    h.spin_until(lambda: not h.node.simulator.pending, what='the reset settled')
    stack, eq = h.node.stack_state()
    assert stack == loaded and eq.stable
    np.testing.assert_allclose(eq.theta, settle_stack(loaded, eq0.theta).theta, atol=1e-12)
    assert eq.theta[2][0] == pytest.approx(eq.theta[2][1], abs=1e-9)      # upright again


def test_a_sideways_buckling_under_a_heavy_head_publishes_no_jump(neck):
    """config/neck.yaml, 3.5 N per head node, m1 rho 0.085 -> 0.07 by rho_cmd: a
    supercritical branch point (the upright neck turns sideways smoothly): no jump on
    ``jumps``, none counted, joint_states reach the buckled state.  The neck is mirror
    symmetric, so which side it buckles to is no model's to decide: one ``undecided``
    message says so, with its uncertainty, counted in ``undecided_total``."""
    n = neck()
    h = n.h
    stack, eq = n.load_head(3.5)
    expected = track_stack(stack, stack.with_module(1, rho=0.07), eq)
    assert expected.jumps == () and len(expected.passages) == 1
    assert 0.07 < expected.passages[0].stack.modules[1].rho < 0.085
    n.rho_pubs['m1'].publish(Float64(data=0.07))
    want = expected.final.theta
    pos, _ = n.wait_state(lambda p: p['m1_rho'] == 0.07, 'the buckled joint_states')
    got = np.array([[pos[f'{m}_theta1'], pos[f'{m}_theta2']] for m in MODULES])
    np.testing.assert_allclose(got, want, atol=1e-8)
    assert abs(want[2][0] - want[2][1]) > 1e-3 and abs(h.node.stack_state()[1].head_angle) > 0.05
    h.spin_until(lambda: len(n.statuses()) == 3 and float(n.statuses()['m1']['rho']) == 0.07
                 and all(v['jumps_total'] == '0' for v in n.statuses().values()),
                 what='statuses after the buckling')
    assert h.node.counters['jumps_total'] == 0
    h.spin_until(lambda: h.undecided, what='the undecided message')
    [msg] = h.undecided
    assert not h.jumps
    v = values(msg)
    assert v['kind'] == 'undecided' and v['module'] == 'm1' and v['cause'] == 'rho_cmd'
    assert float(v['rho']) == expected.undecided[0].stack.modules[1].rho
    assert 0.0 < float(v['rho_uncertainty']) < 1e-9 and 0.0 < float(v['s_uncertainty']) < 1e-8
    assert [float(v[f'{m}_theta1']) for m in MODULES] == list(expected.undecided[0].theta[:, 0])
    assert msg.level == DiagnosticStatus.WARN and 'one side' in msg.message
    assert h.node.counters['undecided_total'] == 1

    # said once on /rosout at INFO, with where it happened, and not as a warning
    def said():
        return [m for m in h.log if 'passed a branch point continuously' in m.msg
                and 'undecided' not in m.msg]
    h.spin_until(said, what='the INFO line of the continuous buckling')
    [line] = said()
    rho = expected.passages[0].stack.modules[1].rho
    assert line.level == Log.INFO and f'm1 rho={rho:.6g}' in line.msg and 'rho_cmd' in line.msg


def test_a_speed_limited_neck_actuator_is_warned_before_it_jumps(neck):
    """A neck has no exact operation range: a speed-limited actuator's path is tracked
    ahead when its target is set, and the jump on it is announced (WARN, counted)
    while the actuator is still on its way; the jump then happens where it said.  (The
    lookahead runs in the time the command path leaves over: at 10 mm/s the actuator
    takes 1.6 s to the fold, room enough on a loaded machine; at 50 mm/s, 0.32 s, the
    warning did not come in about 1 of 8 runs of the node test files at load 5-6.)"""
    n = neck()
    h = n.h
    stack, eq = n.load_head(3.5)
    expected = track_stack(stack, stack.with_module(2, rho=0.12), eq)
    assert [j.kind for j in expected.jumps] == ['fold']
    fold = expected.jumps[0].stack.modules[2].rho                 # ~0.0964, from 0.08
    assert h.node.set_parameters([Parameter('m2.max_rho_rate', value=0.01)])[0].successful
    n.rho_pubs['m2'].publish(Float64(data=0.12))
    said = lambda: h.warnings(f'm2: rho_cmd to rho=0.12 leaves the stable branch at '  # noqa
                              f'rho={fold!r} (fold): the mechanism will jump there')
    h.spin_until(said, what='the early warning')
    assert h.node.counters['jump_warnings'] == 1
    assert h.node.counters['jumps_total'] == 0 and not h.jumps    # 16 mm to go at 10 mm/s
    h.spin_until(lambda: h.jumps, what='the jump')
    v = values(h.jumps[-1])
    assert v['module'] == 'm2' and v['kind'] == 'fold'
    assert float(v['rho']) == pytest.approx(fold, abs=1e-8)
    assert h.node.counters['jump_warnings'] == 1


def test_head_load_jump_is_named_after_the_head_module(neck):
    n = neck()
    h = n.h
    stack0, eq0 = h.node.stack_state()
    expected = track_stack(stack0, stack0.with_module(2, f3y=-10.0, f4y=-10.0), eq0)
    # a continuous sideways buckling at -3.91 N, then a fold at -7.20 N per head node
    assert [j.kind for j in expected.jumps] == ['fold'] and len(expected.passages) == 1
    # both head forces in one atomic parameter set: one symmetric path
    result = h.node.set_parameters_atomically([Parameter('m2.force_a3', value=[0.0, -10.0]),
                                               Parameter('m2.force_a4', value=[0.0, -10.0])])
    assert result.successful
    h.spin_until(lambda: h.jumps, what='a jump')
    v = values(h.jumps[-1])
    assert v['module'] == 'm2' and v['kind'] == 'fold'
    assert v['cause'] == 'parameter m2.force_a3, m2.force_a4'
    assert float(v['rho']) == 0.08
    assert float(v['f3y']) == pytest.approx(expected.jumps[0].stack.modules[2].f3y, abs=1e-9)
    np.testing.assert_allclose(_angles(v, 'to'), expected.jumps[0].to_theta, atol=1e-9)


def test_bad_input_on_a_stack_module_is_dropped_and_counted(neck):
    n = neck()
    h = n.h

    def rejected(key, send):
        h.spin_until(lambda: h.counter(key) is not None, what='/diagnostics')
        before = h.counter(key)
        state = h.node.stack_state()
        send()
        h.spin_until(lambda: h.counter(key) == before + 1, what=f'{key} + 1')
        assert h.node.stack_state() == state
    rejected('rejected_non_finite', lambda: n.rho_pubs['m1'].publish(Float64(data=math.nan)))
    rejected('rejected_out_of_range', lambda: n.rho_pubs['m2'].publish(Float64(data=0.5)))
    rejected('rejected_non_finite',
             lambda: n.force_pubs[('m2', 'a3')].publish(Vector3(x=math.inf, y=0.0)))
    rejected('rejected_unknown_joint',
             lambda: h.jc_pub.publish(JointState(name=['m1_rho', 'm7_rho'],
                                                 position=[0.09, 0.09])))
    rejected('rejected_size_mismatch',
             lambda: h.jc_pub.publish(JointState(name=['m0_rho', 'm1_rho'], position=[0.09])))
    pos, _ = n.joints()
    assert [pos[f'{m}_rho'] for m in MODULES] == [0.09, 0.085, 0.08]
    assert h.node.counters['callback_exceptions'] == 0


def test_force_topics_of_a_stack_module_are_tracked_in_the_base_frame(neck):
    n = neck()
    h = n.h
    stack0, eq0 = h.node.stack_state()
    n.force_pubs[('m1', 'a3')].publish(Vector3(x=0.5, y=0.0, z=7.0))     # z is ignored
    h.spin_until(lambda: h.node.stack_state()[0].modules[1].f3x == 0.5, what='m1 force')
    stack, eq = h.node.stack_state()
    expected = track_stack(stack0, stack0.with_module(1, f3x=0.5), eq0)
    assert stack == stack0.with_module(1, f3x=0.5)
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    pos, _ = n.wait_state(lambda p: p['m0_theta1'] == eq.theta[0][0], 'pushed state')
    # pushed sideways (+x) at m1's A3: the head moves toward +x
    h.spin_until(lambda: n.head[-1].pose.position.x > 0.046, what='head moved')
    assert n.head[-1].pose.position.x == pytest.approx(eq.head_position[0], abs=1e-12)


def test_joint_commands_the_node_keeps_up_with_are_answered_one_to_one(neck):
    """Each of 60 three-module joint_commands sent once the previous one is answered (the
    node keeps up): every one is processed, none coalesced, and the joint_states that
    answers it carries exactly the commanded rhos (read from the command's bytes,
    published as bytes; every m0 value is new, so a publish_rate tick cannot pass for it)."""
    n = neck()
    h = n.h
    before = h.node.counters
    for i in range(60):
        rhos = [rho + 1e-3 * math.sin(0.3 * i + j + 0.5) + 1e-13 * i
                for j, rho in enumerate((0.09, 0.085, 0.08))]
        sent = len(h.joint_states)
        h.jc_pub.publish(JointState(name=[f'{m}_rho' for m in MODULES], position=rhos))
        h.spin_until(lambda: len(h.joint_states) > sent and
                     h.joint_states[-1].position[0] == rhos[0], what=f'answer to command {i}')
        pos, _ = n.joints()
        assert [pos[f'{m}_rho'] for m in MODULES] == rhos
    after = h.node.counters
    assert after['commands_processed'] - before['commands_processed'] == 60
    assert after['commands_coalesced'] == before['commands_coalesced']


def _send_burst(n, burst, names):
    """Publish every command of ``burst`` at once, before the node spins again: they all
    wait in its joint_commands queue for one callback.  Returns the joint_states seen
    before, to find the answers after."""
    h = n.h
    pub = h.client.create_publisher(JointState, 'joint_commands', STREAM_QOS)
    h.spin_until(lambda: pub.get_subscription_count() > 0, what='burst publisher matched')
    sent = len(h.joint_states)
    for rhos, joints in zip(burst, names):
        pub.publish(JointState(name=joints, position=rhos))
    return sent


#: every rho new (none is the start's, so a publish_rate tick cannot pass for an answer)
BURST = [[rho + 1e-3 * math.sin(0.7 * i + j + 0.5) + 1e-13 * i
          for j, rho in enumerate((0.09, 0.085, 0.08))] for i in range(10)]
ALL_RHOS = [f'{m}_rho' for m in MODULES]


def test_a_burst_of_joint_commands_behind_one_callback_is_answered_command_by_command(
        neck, monkeypatch):
    """Ten three-module joint_commands waiting behind one callback, within the backlog's
    time budget (made a minute here, so that a loaded machine cannot spend it): each is
    tracked and answered by a joint_states carrying exactly its rhos, in the order sent;
    none is coalesced.  (10 small neck commands take ~3 ms, under the real 10 ms.)"""
    monkeypatch.setattr(commands, 'BACKLOG_BUDGET_NS', 60 * 10**9)
    n = neck()
    h = n.h
    before = h.node.counters
    sent = _send_burst(n, BURST, [ALL_RHOS] * len(BURST))
    h.spin_until(lambda: any(m.position[0] == BURST[-1][0] for m in h.joint_states[sent:]),
                 what='the answer to the last command of the burst')
    # in order of first appearance (a publish_rate tick may repeat the state it holds)
    answered = dict.fromkeys(tuple(m.position[0::3]) for m in h.joint_states[sent:])
    assert [list(rhos) for rhos in answered if list(rhos) in BURST] == BURST
    after = h.node.counters
    assert after['commands_processed'] - before['commands_processed'] == len(BURST)
    assert after['commands_coalesced'] == before['commands_coalesced']


def test_a_burst_beyond_the_budget_keeps_the_latest_target_of_each_key(neck, monkeypatch):
    """The same burst with the budget spent from the start (0): only the latest command
    of each key is tracked -- here the last one naming all three modules and the last one
    naming m0 alone, in the order of their arrival -- and the others are counted as
    coalesced: processed + coalesced = sent."""
    monkeypatch.setattr(commands, 'BACKLOG_BUDGET_NS', 0)
    n = neck()
    h = n.h
    names = [['m0_rho'] if i in (3, 7) else ALL_RHOS for i in range(len(BURST))]
    burst = [rhos[:1] if joints == ['m0_rho'] else rhos for rhos, joints in zip(BURST, names)]
    before = h.node.counters
    sent = _send_burst(n, burst, names)
    h.spin_until(lambda: any(m.position[0] == burst[-1][0] for m in h.joint_states[sent:]),
                 what='the answer to the last command of the burst')
    m0_answers = dict.fromkeys(m.position[0] for m in h.joint_states[sent:]
                               if m.position[0] in [rhos[0] for rhos in burst])
    assert list(m0_answers) == [burst[7][0], burst[9][0]]
    assert [m.position[0::3] for m in h.joint_states[sent:]
            if m.position[0] == burst[9][0]][0].tolist() == burst[9]
    after = h.node.counters
    assert after['commands_processed'] - before['commands_processed'] == 2
    assert after['commands_coalesced'] - before['commands_coalesced'] == len(burst) - 2
