"""Every number msg_docs/ shows comes from the node as it is now (issue 33).

The test reads the pages (their example messages, example log lines and figures in the
text), runs the scenario each example names through a node, and compares: a value with
17 significant digits to 1e-9 relative (the last digits may differ between BLAS kernels),
a shortened one (``0.7227...``, ``0.0792``) to the digits shown; text exactly.  QoS depths
are compared with the node's endpoints, and the time budgets and limits the pages quote
with the constants of the code.  Before it, jumps.md's fig. 8a landing said 1.41915 where
the node gives 1.41894, force_a3/a4.md a queue depth of 100 where the node keeps 1000, and
the early-warning line a fold at 0.0964 no configuration of the pages gives.
"""
import math
from pathlib import Path
import re

from geometry_msgs.msg import PoseStamped
import pytest
from std_msgs.msg import Float64
import yaml

from test_node import fig8a_overrides, LATCHED_QOS, PUB_QOS, values
from test_node_neck import NECK_CONFIG

pytestmark = pytest.mark.ros

DOCS = Path(__file__).resolve().parents[1] / 'msg_docs'
NUMBER = re.compile(r'-?\d+(?:\.\d+)?(?:e-?\d+)?')


def page(name):
    return (DOCS / name).read_text()


def yaml_blocks(text):
    return [yaml.safe_load(b) for b in re.findall(r'```yaml\n(.*?)```', text, re.S)]


def block_with(name, words):
    """The example message of page ``name`` whose text holds ``words``."""
    text = page(name)
    for raw in re.findall(r'```yaml\n(.*?)```', text, re.S):
        if words in raw:
            return yaml.safe_load(raw)
    raise AssertionError(f'{name}: no example with {words!r}')


def agrees(shown, actual):
    """``shown`` (documented text) agrees with ``actual`` (the node's value or text)."""
    shown, actual = str(shown), str(actual)
    if shown.endswith('...'):                # digits shown: one unit of the last one
        digits = shown[:-3]
        places = len(digits.split('.')[1]) if '.' in digits else 0
        return abs(float(digits) - float(actual)) <= 10.0 ** -places
    try:
        a, b = float(shown), float(actual)
    except ValueError:
        return shown == actual
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def same_text(shown, actual):
    """Texts equal but for their numbers, which agree as :func:`agrees` says."""
    assert NUMBER.sub('#', shown) == NUMBER.sub('#', actual), (shown, actual)
    for a, b in zip(NUMBER.findall(shown), NUMBER.findall(actual)):
        places = len(a.split('.')[1]) if '.' in a else 0
        assert abs(float(a) - float(b)) <= 0.5 * 10.0 ** -places + 1e-12, (shown, actual)


def check_message(documented, msg):
    """A documented DiagnosticStatus (parsed YAML) against the node's message."""
    got = values(msg)
    for key in ('name', 'message'):
        if key in documented:
            same_text(documented[key], getattr(msg, key))
    if 'level' in documented:
        assert ord(documented['level']) == ord(msg.level)
    shown = {kv['key']: kv['value'] for kv in documented['values']}
    assert shown, documented
    for key, value in shown.items():
        assert agrees(value, got[key]), (key, value, got[key])


# ---------------------------------------------------------------------------
# examples of one module


def test_fig8a_examples_jumps_equilibrium_and_reset(harness):
    """jumps.md and equilibrium.md: fig. 8a's lower branch, rho 0.5 -> 0.1 (rho_cmd)."""
    h = harness(fig8a_overrides()).ready()
    h.command_rho(0.1)
    h.spin_until(lambda: h.jumps, what='the jump')
    check_message(block_with('jumps.md', 'branch_point'), h.jumps[-1])
    table = re.search(r'\| `message` \| e\.g\. `([^`]*)`', page('jumps.md')).group(1)
    same_text(table, h.jumps[-1].message)
    status = h.wait_status(lambda v: v['jumps_total'] == '1' and float(v['rho']) == 0.1)
    check_message(block_with('equilibrium.md', 'last_jump_rho'), h.equilibrium[-1])
    assert status['module'] == 'm0'


def test_reset_message_example(harness):
    from std_srvs.srv import Trigger
    h = harness().ready()
    h.spin_until(h.reset_client.service_is_ready, what='reset service')
    response = h.call(h.reset_client.call_async(Trigger.Request()), 'reset')
    shown = re.search(r'e\.g\. `(reset to the initial state;[^`]*)`', page('reset.md')).group(1)
    numbers = NUMBER.findall(shown.replace('...', ''))
    assert NUMBER.sub('#', shown.replace('...', '')) == NUMBER.sub('#', response.message)
    for a, b in zip(NUMBER.findall(shown.replace('...', '')), NUMBER.findall(response.message)):
        assert agrees(a + ('...' if '.' in a and len(a) > 4 else ''), b), (a, b)
    assert numbers


def test_unloaded_actuator_force(harness):
    h = harness().ready()
    rho, force = re.search(r'Unloaded at rho = ([\d.]+) it is (-?[\d.]+) N',
                           page('joint_states.md')).groups()
    state = h.state()
    assert state[0] == float(rho) and state[3] == pytest.approx(float(force), abs=1e-9)


def test_trajectory_example_and_motion_messages(harness):
    """joint_trajectory.md's ros2 topic pub line on fig. 8a's lower branch: C1 crossed on the
    way (a jump caused by the trajectory), and ~/motion's messages as motion.md shows them."""
    from builtin_interfaces.msg import Duration
    from diagnostic_msgs.msg import DiagnosticStatus
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    text = page('joint_trajectory.md')
    fields = yaml.safe_load(re.search(r'JointTrajectory \\\n\s*"(\{.*\})"', text).group(1))
    msg = JointTrajectory(joint_names=fields['joint_names'], points=[
        JointTrajectoryPoint(positions=[float(v) for v in p['positions']],
                             time_from_start=Duration(**p['time_from_start']))
        for p in fields['points']])
    c1 = re.search(r'the branch point C1 at rho = ([\d.]+)', text).group(1)
    h = harness(fig8a_overrides()).ready()
    motion = []
    h.client.create_subscription(DiagnosticStatus, h.private('motion'), motion.append,
                                 LATCHED_QOS)
    pub = h.client.create_publisher(JointTrajectory, 'joint_trajectory', PUB_QOS)
    h.spin_until(lambda: pub.get_subscription_count() > 0 and motion, what='~/motion')
    pub.publish(msg)
    h.spin_until(lambda: motion[-1].message.startswith('succeeded'), timeout=60,
                 what='the trajectory to succeed')
    jump = values(h.jumps[-1])
    assert jump['cause'] == 'joint_trajectory' and agrees(c1 + '...', jump['rho'])
    shown = re.search(r'\| `message` \| `<state>: <what>`, e\.g\. (.*) \|', page('motion.md'))
    examples = re.findall(r'`([^`]*)`', shown.group(1))
    said = [m.message for m in motion]
    assert examples[0] in said and examples[1] in said, (examples, said)


# ---------------------------------------------------------------------------
# examples of the neck (config/neck.yaml)


def neck_harness(harness, **overrides):
    h = harness(cli_args=['--ros-args', '--params-file', str(NECK_CONFIG)],
                parameters=overrides).ready()
    return h


def test_neck_jump_example(harness):
    """jumps.md's stack example: head load 3.5 N per head node, m0/rho_cmd 0.09 -> 0.05:
    a smooth buckling first (INFO line), then a fold of the buckled neck."""
    text = page('jumps.md')
    load, start, end, buckles = re.search(
        r'head load ([\d.]+) N per head node, `m0/rho_cmd` ([\d.]+) -> ([\d.]+):\n'
        r'at m0 rho = ([\d.]+) the neck buckles', text).groups()
    h = neck_harness(harness, **{'m2.force_a3': [0.0, -float(load)],
                                 'm2.force_a4': [0.0, -float(load)]})
    assert h.node.simulator.modules[0].rho == float(start)
    pub = h.client.create_publisher(Float64, 'm0/rho_cmd', PUB_QOS)
    h.spin_until(lambda: pub.get_subscription_count() > 0, what='m0/rho_cmd')
    pub.publish(Float64(data=float(end)))
    h.spin_until(lambda: h.jumps, what='the neck jump')
    documented = block_with('jumps.md', 'fold of the stack')
    check_message(documented, h.jumps[-1])
    got = values(h.jumps[-1])
    # the values the example's comments list, "key value" or "key (a, b)"
    comments = '\n'.join(re.findall(r'^# (.*)$', re.search(
        r'```yaml\n(name: .tensegrity: m0 jump.*?)```', text, re.S).group(1), re.M))
    for key, number in re.findall(r'(from_theta2|s|m1_rho|m2_rho) (-?[\d.]+)', comments):
        assert agrees(number + '...', got[key]), (key, number, got[key])
    for side, m, a, b in re.findall(r'(from|to)_(m\d) \((-?[\d.]+), (-?[\d.]+)\)', comments):
        for n, shown in ((1, a), (2, b)):
            key = f'{side}_{m}_theta{n}'
            assert agrees(shown + '...', got[key]), (key, shown, got[key])
    to = re.search(r'to_theta1/2 (-?[\d.]+)', comments).group(1)
    assert agrees(to + '...', got['to_theta1']) and agrees(to + '...', got['to_theta2'])
    h.spin_until(lambda: any('passed a branch point continuously' in m.msg for m in h.log),
                 what='the INFO line of the smooth buckling')
    passage = next(m.msg for m in h.log if 'passed a branch point continuously' in m.msg)
    rho = float(re.search(r'm0 rho=([\d.]+)', passage).group(1))
    assert agrees(buckles + '...', rho), (buckles, passage)


def test_neck_early_warning_example(harness):
    """jumps.md's early-warning line: config/neck.yaml, m2 speed-limited, m2/rho_cmd."""
    line = re.search(r'`(m2: rho_cmd to rho=[^`]*)`', page('jumps.md')).group(1)
    rate = float(re.search(r'`m2.max_rho_rate: ([\d.]+)`', page('jumps.md')).group(1))
    target = float(re.search(r'rho_cmd to rho=([\d.]+)', line).group(1))
    h = neck_harness(harness, **{'m2.max_rho_rate': rate})
    pub = h.client.create_publisher(Float64, 'm2/rho_cmd', PUB_QOS)
    h.spin_until(lambda: pub.get_subscription_count() > 0, what='m2/rho_cmd')
    pub.publish(Float64(data=target))
    h.spin_until(lambda: h.warnings('leaves the stable branch'), what='the early warning')
    said = h.warnings('leaves the stable branch')[0]
    shown_end = re.search(r'branch at rho=([\d.]+)\.\.\.', line).group(1)
    got_end = re.search(r'branch at rho=([\d.e-]+)', said).group(1)
    assert agrees(shown_end + '...', got_end), (line, said)
    assert NUMBER.sub('#', line.replace('...', '')) == NUMBER.sub('#', said), (line, said)


def test_neck_head_pose_figures(harness):
    x, y = re.search(r'level at x = ([\d.]+) m .*?y ~ ([\d.]+) m', page('head_pose.md'),
                     re.S).groups()
    h = neck_harness(harness)
    head = []
    h.client.create_subscription(PoseStamped, h.private('head_pose'), head.append, LATCHED_QOS)
    h.spin_until(lambda: head, what='head_pose')
    p = head[-1].pose
    assert agrees(x + '...', p.position.x) and agrees(y + '...', p.position.y)
    assert p.orientation.z == pytest.approx(0.0, abs=1e-9)          # level


# ---------------------------------------------------------------------------
# QoS depths and the constants the pages quote

#: page -> (the node's endpoint, publisher or subscription, the QoS constant of its depth;
#: None: one per module) for the QoS lines (the graph does not report history depths)
ENDPOINTS = {
    'rho_cmd.md': ('m0/rho_cmd', 'sub', 'COMMAND_QOS'),
    'force_a3.md': ('m0/force_a3', 'sub', 'COMMAND_QOS'),
    'force_a4.md': ('m0/force_a4', 'sub', 'COMMAND_QOS'),
    'joint_commands.md': ('joint_commands', 'sub', 'COMMAND_QOS'),
    'joint_trajectory.md': ('joint_trajectory', 'sub', 'COMMAND_QOS'),
    'joint_states.md': ('joint_states', 'pub', 'STATE_QOS'),
    'stable.md': ('~stable', 'pub', 'STATUS_QOS'), 'equilibrium.md': ('~equilibrium', 'pub', None),
    'jumps.md': ('~jumps', 'pub', 'JUMPS_QOS'), 'motion.md': ('~motion', 'pub', 'MOTION_QOS'),
    'head_pose.md': ('~head_pose', 'pub', 'HEAD_QOS'),
    'markers.md': ('~markers', 'pub', 'MARKERS_QOS'),
    'diagnostics.md': ('/diagnostics', 'pub', 'STATE_QOS'),
    'tf.md': (None, 'pub', 'TF_QOS'),
}


def test_qos_depths_are_the_nodes(harness):
    from rclpy.qos import DurabilityPolicy

    from tensegrity_ros.ros import qos as node_qos
    h = harness().ready()
    node = h.node

    def endpoint(name, side):
        full = h.private(name[1:]) if name.startswith('~') else (
            name if name.startswith('/') else f'{h.ns}/{name}')
        infos = (node.get_publishers_info_by_topic(full) if side == 'pub'
                 else node.get_subscriptions_info_by_topic(full))
        return next(i for i in infos if i.node_name == node.get_name()).qos_profile
    table = page('README.md')
    for name, (topic, side, constant) in ENDPOINTS.items():
        line = re.search(r'\* \*\*QoS:\*\* ([^\n]*)', page(name)).group(1)
        depth = re.search(r'keep last (\d+|N)', line).group(1)
        if constant is None:
            assert depth == 'N', (name, line)
        else:
            assert int(depth) == getattr(node_qos, constant).depth, (name, line)
        latched = 'transient local' in line
        if topic is None:
            assert latched == (node_qos.TF_QOS.durability ==
                               DurabilityPolicy.TRANSIENT_LOCAL)
            continue
        qos = endpoint(topic, side)
        assert latched == (qos.durability == DurabilityPolicy.TRANSIENT_LOCAL), (name, line)
        row = next(r for r in table.splitlines() if f'[{name}]' in r)
        shown = re.search(r'depth (\d+|N)', row).group(1)
        assert shown == depth, (name, row, line)


def test_the_constants_the_pages_quote():
    from tensegrity_ros.core.module import model as module, supported_range
    from tensegrity_ros.core.simulation.command_coalescing import BACKLOG_BUDGET_NS
    from tensegrity_ros.core.simulation.simulator import DEFAULT_TIME_BUDGET, DEFAULT_WORK_LIMIT
    from tensegrity_ros.ros import incidents, qos
    text = {name: page(name) for name in ('README.md', 'diagnostics.md', 'force_a3.md',
                                          'force_a4.md', 'jumps.md', 'markers.md')}
    budget = f'{BACKLOG_BUDGET_NS // 1_000_000} ms'
    assert budget == '10 ms' and budget in text['README.md'] and budget in text['diagnostics.md']
    assert f'{DEFAULT_TIME_BUDGET * 1000:g} ms' in text['diagnostics.md']
    assert f'more than {DEFAULT_WORK_LIMIT:g} s of tracking' in text['diagnostics.md']
    assert f'once per {incidents.WARN_THROTTLE_SEC:g} s' in text['README.md']
    depth = qos.COMMAND_QOS.depth
    assert f'queue of {depth}' in text['README.md'] and f'queue of {depth}' in \
        text['diagnostics.md']
    assert f'{depth / 5000:g} s of a 5 kHz stream' in text['diagnostics.md']

    def power(x):
        return f'1e{round(math.log10(x))}'
    for name in ('diagnostics.md', 'force_a3.md', 'force_a4.md'):
        assert power(module.MAX_MAGNITUDE) in text[name], name
        assert power(supported_range.LOAD_RATIO) in text[name], name
    assert f'{DEFAULT_TIME_BUDGET * 1000:g} ms each at most' in text['jumps.md']
    rates = {p[0]: p[1] for p in __import__('tensegrity_ros.ros.parameters',
                                            fromlist=['x']).NODE_PARAMETERS}
    assert f"default {rates['markers_rate']:g}, 0 = off" in text['markers.md']
