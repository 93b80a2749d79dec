"""Hostile and odd input through the node's ROS interface (issue 12).

Every test drives the node as a client would (topics, parameters, /rosout, the process'
exit status and stderr) and asserts what comes back, so that it holds whatever the node
is built from.  In-process nodes use the Harness of test_node.py (spun until a condition,
no sleeps); processes are started the way ``make run`` starts the node.
"""
import os
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Vector3
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from tensegrity_ros.core import equilibria, ModuleParams, settle, track_module
from test_node import LATCHED_QOS, ROOT, STREAM_QOS, TIMEOUT

pytestmark = pytest.mark.ros

NECK_CONFIG = ROOT / 'config' / 'neck.yaml'
#: The jumps topic's QoS with room for every jump of a burst (test_node's keeps 10).
DEEP_LATCHED_QOS = QoSProfile(depth=1000, reliability=LATCHED_QOS.reliability,
                              durability=LATCHED_QOS.durability)


def run_node(*ros_args, timeout=TIMEOUT):
    """Start the node process; returns (exit status, stdout, stderr) once it exits."""
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    assert env.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
    proc = subprocess.run(
        [sys.executable, '-m', 'tensegrity_ros.ros.node', '--ros-args',
         '-r', f'__ns:=/hardening_{os.getpid()}', *ros_args],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
    return proc.returncode, proc.stdout, proc.stderr


def fatal_lines(err):
    return [line for line in err.splitlines() if 'FATAL' in line]


# ---------------------------------------------------------------------------
# An unusable parameter file: one FATAL line, exit 2 (README, Quick start)


@pytest.mark.parametrize('text, says', [
    ('/**:\n  ros__parameters: [a\n', 'invalid YAML'),
    ('- a\n- b\n', 'not a ROS 2 parameter file'),
    ('just a string\n', 'not a ROS 2 parameter file'),
], ids=['invalid-yaml', 'top-level-list', 'top-level-scalar'])
def test_unusable_parameter_file_is_one_fatal_line_and_exit_2(tmp_path, text, says):
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    status, out, err = run_node('--params-file', str(path))
    assert status == 2, (out, err)
    assert 'Traceback' not in out + err, err
    lines = fatal_lines(err)
    assert len(lines) == 1, err
    assert says in lines[0] and str(path) in lines[0]


def test_missing_parameter_file_is_one_fatal_line_and_exit_2(tmp_path):
    path = tmp_path / 'absent.yaml'
    status, out, err = run_node('--params-file', str(path))
    assert status == 2, (out, err)
    assert 'Traceback' not in out + err, err
    assert len(fatal_lines(err)) == 1 and str(path) in err


# ---------------------------------------------------------------------------
# Rates whose period cannot be represented are refused with a reason


@pytest.mark.parametrize('rate', [5e-324, 1e-300, 1e-3])
def test_absurd_markers_rate_is_refused_at_runtime(harness, rate):
    h = harness().ready()
    before = h.node.counters['callback_exceptions']
    result = h.call(h.params.set_parameters([Parameter('markers_rate', value=rate)]),
                    'set markers_rate')
    assert not result.results[0].successful
    assert 'markers_rate' in result.results[0].reason
    h.spin_until(lambda: h.counter('rejected_parameter_value') == 1, what='the refusal counted')
    assert h.counter('callback_exceptions') == before == 0
    # still served: 0 (off) and a sane rate are accepted
    for ok in (0.0, 0.5):
        result = h.call(h.params.set_parameters([Parameter('markers_rate', value=ok)]),
                        'set markers_rate')
        assert result.results[0].successful, result.results[0].reason


def test_absurd_markers_rate_at_start_up_is_exit_2():
    status, out, err = run_node('--params-file', str(ROOT / 'config' / 'default.yaml'),
                                '-p', 'markers_rate:=1e-300')
    assert status == 2, (out, err)
    assert 'Traceback' not in out + err
    lines = fatal_lines(err)
    assert len(lines) == 1 and 'markers_rate' in lines[0], err


# ---------------------------------------------------------------------------
# Outside text in a log line is shortened and escaped


def test_huge_joint_name_is_shortened_in_the_log(harness):
    h = harness().ready()
    name = 'x' * 1_000_000 + '\n\x1b[31m'
    h.jc_pub.publish(JointState(name=[name], position=[0.6]))
    h.spin_until(lambda: h.warnings('rejected_unknown_joint'), what='the WARN line')
    (line,) = h.warnings('rejected_unknown_joint')
    assert len(line) < 1000
    assert 'more characters' in line
    assert '\n' not in line and '\x1b' not in line
    assert h.state()[0] == 0.75


def test_control_characters_in_a_joint_name_are_escaped(harness):
    h = harness().ready()
    h.jc_pub.publish(JointState(name=['m9_rho\r\x1b[2J'], position=[0.6]))
    h.spin_until(lambda: h.warnings('rejected_unknown_joint'), what='the WARN line')
    (line,) = h.warnings('rejected_unknown_joint')
    assert '\\r' in line and '\\x1b' in line
    assert '\r' not in line and '\x1b' not in line


# ---------------------------------------------------------------------------
# commands_processed counts accepted command messages (diagnostics.md)


def test_commands_processed_counts_messages_not_joint_targets(harness):
    h = harness(cli_args=['--ros-args', '--params-file', str(NECK_CONFIG)])
    h.spin_until(lambda: h.jc_pub.get_subscription_count() > 0 and h.joint_states
                 and h.counter('commands_processed') is not None, what='discovery')
    assert h.counter('commands_processed') == 0
    h.jc_pub.publish(JointState(name=['m0_rho', 'm2_rho'], position=[0.1, 0.075]))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.1, what='rho 0.1')
    n = len(h.diagnostics)
    h.spin_until(lambda: len(h.diagnostics) > n, what='one more /diagnostics')
    assert h.counter('commands_processed') == 1


def test_commands_processed_counts_a_speed_limited_joint_commands_once(harness):
    h = harness({'m0.max_rho_rate': 100.0}).ready()
    h.spin_until(lambda: h.counter('commands_processed') is not None, what='/diagnostics')
    h.jc_pub.publish(JointState(name=['m0_rho'], position=[0.8]))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.8, what='rho 0.8')
    n = len(h.diagnostics)
    h.spin_until(lambda: len(h.diagnostics) > n, what='one more /diagnostics')
    assert h.counter('commands_processed') == 1


# ---------------------------------------------------------------------------
# Jump log lines are throttled; the jumps topic carries every jump


def _force_toggles():
    """Force messages that snap the unloaded module between its branches, with the state
    each one ends in (the core tracker, the reference of test_tracking.py)."""
    p = ModuleParams.paper(0.75)
    eq = settle(p, [0.7, 0.7])
    steps, jumps = [], 0
    for force in (-60.0, 60.0) * 3:
        for field in ('f3y', 'f4y'):
            track = track_module(p, p.with_(**{field: force}), eq.theta)
            p, eq = track.end, track.final
            jumps += len(track.jumps)
            steps.append((field, force, eq.theta1))
    return steps, jumps


def test_repeated_jumps_are_all_published_but_logged_throttled(harness):
    steps, expected_jumps = _force_toggles()
    assert expected_jumps == 6
    h = harness().ready()
    start = h.client.get_clock().now().nanoseconds
    for field, force, theta1 in steps:
        which = 'a3' if field == 'f3y' else 'a4'
        h.force_pubs[which].publish(Vector3(x=0.0, y=force, z=0.0))
        h.spin_until(lambda: abs(h.state()[1] - theta1) < 1e-9, what=f'{field}={force}')
    h.spin_until(lambda: len(h.jumps) == expected_jumps, what='every jump on jumps')
    elapsed = (h.client.get_clock().now().nanoseconds - start) * 1e-9
    h.spin_until(lambda: h.warnings(': jump ('), what='a jump WARN line')
    lines = h.warnings(': jump (')
    assert len(lines) <= 1 + elapsed / 2.0, (elapsed, lines)
    assert len(lines) < expected_jumps


# ---------------------------------------------------------------------------
# Two nodes with one fully qualified name: the second one says so at start-up


def test_second_node_with_the_same_name_warns_at_start_up(harness):
    h = harness().ready()
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'tensegrity_ros.ros.node', '--ros-args', '-r', f'__ns:={h.ns}'],
        cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    try:
        h.spin_until(lambda: any('already running' in line for line in lines) or
                     proc.poll() is not None, what='the duplicate-name warning')
        warning = next(line for line in lines if 'already running' in line)
        assert 'WARN' in warning and f'{h.ns}/tensegrity' in warning
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=TIMEOUT)
        reader.join(timeout=TIMEOUT)
    assert proc.returncode == 0


def test_a_node_alone_does_not_warn_about_its_name(harness):
    h = harness().ready()
    h.spin_until(lambda: h.counter('commands_processed') is not None, what='/diagnostics')
    n = len(h.diagnostics)
    h.spin_until(lambda: len(h.diagnostics) > n + 60, what='3 s of /diagnostics at 20 Hz')
    assert not h.warnings('already running')


# ---------------------------------------------------------------------------
# Load: a burst of commands each crossing a fold; none is lost without a trace


def _unique_state(f4y):
    """The only stable equilibrium of the unloaded default module with force_a4 (0, f4y)
    (so the end state does not depend on which commands of a burst were tracked)."""
    found = [e for e in equilibria(ModuleParams.paper(0.75).with_(f4y=f4y)) if e.stable]
    assert len(found) == 1
    return found[0]


def test_burst_of_fold_crossing_commands_is_processed_or_counted(harness):
    """300 force_a4 messages at 1 kHz, each flipping the module through a fold (~15 ms of
    tracking each): every one is processed, coalesced or rejected, and counted."""
    count = 300
    forces = [60.0 if i % 2 else -60.0 for i in range(count)]       # ends on +60
    end = _unique_state(forces[-1])
    h = harness().ready()
    pub = h.client.create_publisher(Vector3, 'm0/force_a4', STREAM_QOS)
    # a queue for every jump: the client takes one message per executor cycle, while a
    # node callback working off a backlog can publish several (the harness keeps 10)
    jumps = []
    h.client.create_subscription(DiagnosticStatus, h.private('jumps'), jumps.append,
                                 DEEP_LATCHED_QOS)
    h.spin_until(lambda: pub.get_subscription_count() > 0 and
                 h.counter('commands_processed') is not None, what='discovery')

    def send():
        start = time.monotonic()
        for i, f in enumerate(forces):
            delay = start + i * 1e-3 - time.monotonic()
            if delay > 0:
                time.sleep(delay)       # paces the stream (1 kHz); not a synchronisation
            pub.publish(Vector3(x=0.0, y=f, z=0.0))

    sender = threading.Thread(target=send)
    sender.start()

    def accounted():
        return (h.counter('commands_processed') + h.counter('commands_coalesced')
                + h.counter('rejected_total'))
    try:
        h.spin_until(lambda: not sender.is_alive() and accounted() >= count,
                     what='every command processed or counted')
    finally:
        sender.join()
    assert accounted() == count
    assert h.counter('rejected_total') == 0
    assert h.counter('commands_processed') >= 1
    h.spin_until(lambda: abs(h.state()[1] - end.theta1) < 1e-9, what='the last force tracked')
    assert h.state()[2] == pytest.approx(end.theta2, abs=1e-9)
    # every jump the node counted is on the topic (how many there are depends on how many
    # forces a loaded machine coalesced: 299 of 300 were once, and that path has none)
    h.spin_until(lambda: len(jumps) == h.counter('jumps_total'), what='every jump published')


# ---------------------------------------------------------------------------
# Joint names are compared exactly


def _serialized_joint_commands(name_bytes, position):
    """A serialized JointState whose one name is ``name_bytes`` exactly (rclpy itself
    cannot publish a NUL inside a string; a C++ publisher can)."""
    placeholder = 'Z' * len(name_bytes)
    raw = serialize_message(JointState(name=[placeholder], position=[position]))
    at = raw.index(placeholder.encode())
    return raw[:at] + name_bytes + raw[at + len(name_bytes):]


@pytest.mark.parametrize('name', [b'm0_rho\x00', b'm0_rho\x00m1', b'\x00m0_rho'])
def test_joint_name_with_a_nul_is_not_m0_rho(harness, name):
    h = harness().ready()
    raw = _serialized_joint_commands(name, 0.6)
    assert deserialize_message(raw, JointState).name[0] in ('m0_rho', '')
    h.rejected('rejected_unknown_joint', lambda: h.jc_pub.publish(raw))
    assert h.state()[0] == 0.75
    line = h.warnings('rejected_unknown_joint')[-1]
    assert '\\x00' in line


def test_serialized_exact_name_is_still_applied(harness):
    h = harness().ready()
    h.jc_pub.publish(_serialized_joint_commands(b'm0_rho', 0.6))
    h.spin_until(lambda: h.joint_states[-1].position[0] == 0.6, what='rho 0.6')


# ---------------------------------------------------------------------------
# Ctrl-C while a callback runs: quiet


@pytest.mark.parametrize('executor_kind', ['events', 'single'])
def test_sigint_while_busy_is_quiet(harness, executor_kind):
    """Commands keep the node busy when SIGINT shuts its context down under a callback:
    exit 0, no FATAL/ERROR line and no traceback from the executor."""
    h = harness(node=False)
    pub = h.client.create_publisher(JointState, f'{h.ns}/joint_commands', STREAM_QOS)
    states = []
    h.client.create_subscription(JointState, f'{h.ns}/joint_states', states.append,
                                 STREAM_QOS)
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'tensegrity_ros.ros.node', '--executor', executor_kind,
         '--ros-args', '-r', f'__ns:={h.ns}'],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        h.spin_until(lambda: states and pub.get_subscription_count() > 0 or
                     proc.poll() is not None, what='the node')
        for i in range(200):
            pub.publish(JointState(name=['m0_rho'], position=[0.7 + 0.001 * (i % 50)]))
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    for bad in ('Traceback', 'Error occurred', '[FATAL]', '[ERROR]'):
        assert bad not in err + out, err
