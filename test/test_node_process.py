"""The node as a process, started the way ``make run`` starts it.

``python -m tensegrity_ros.ros.node --ros-args --params-file config/default.yaml``: it must
publish, exit 0 without a traceback on SIGINT (Ctrl-C) and SIGTERM, and refuse an unusable
configuration with exit code 2 and a clear message (no traceback).  The subprocess
inherits this session's loopback-only discovery and ROS_DOMAIN_ID (test/conftest.py).
"""
import contextlib
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'config' / 'default.yaml'
TIMEOUT = float(os.environ.get('TENSEGRITY_TEST_TIMEOUT', '30'))


def start_node(namespace, *ros_args, executor=None):
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    assert env.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
    options = [] if executor is None else ['--executor', executor]
    return subprocess.Popen(
        [sys.executable, '-m', 'tensegrity_ros.ros.node', *options, '--ros-args',
         '--params-file', str(CONFIG), '-r', f'__ns:={namespace}', *ros_args],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@contextlib.contextmanager
def reaped(proc):
    """Run the block; a node process it leaves running is killed and reaped."""
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


@pytest.fixture
def client():
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('process_test_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    yield node, executor
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def spin_until(node, executor, predicate, proc, what):
    clock = node.get_clock()
    deadline = clock.now().nanoseconds + int(TIMEOUT * 1e9)
    while not predicate():
        if proc.poll() is not None:
            out, err = proc.communicate()
            raise AssertionError(f'node exited early ({proc.returncode}) waiting for {what}:\n'
                                 f'{out}\n{err}')
        if clock.now().nanoseconds > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.parametrize('executor_kind, sig', [
    ('events', signal.SIGINT), ('events', signal.SIGTERM), ('single', signal.SIGINT)],
    ids=['events-SIGINT', 'events-SIGTERM', 'single-SIGINT'])
def test_signal_exits_cleanly(client, executor_kind, sig):
    node, executor = client
    namespace = f'/proc_{executor_kind}_{sig.name.lower()}_{os.getpid()}'
    states, stable = [], []
    node.create_subscription(JointState, f'{namespace}/joint_states', states.append, 10)
    node.create_subscription(
        Bool, f'{namespace}/tensegrity/stable', stable.append,
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    proc = start_node(namespace, executor=executor_kind)
    with reaped(proc):
        spin_until(node, executor, lambda: states and stable, proc, 'joint_states and stable')
        assert states[-1].position[0] == 0.75
        assert stable[-1].data is True
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err and 'Traceback' not in out, err


def test_too_many_modules_exit_2_with_a_clear_message():
    names = ', '.join(f'm{i}' for i in range(21))
    proc = start_node(f'/proc_many_{os.getpid()}', '-p', f'modules:=[{names}]')
    with reaped(proc):
        out, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2, (out, err)
    assert 'a node hosts 1 to 20 modules' in err
    assert 'Traceback' not in err + out


def test_invalid_parameter_file_value_exits_2():
    proc = start_node(f'/proc_bad_{os.getpid()}', '-p', 'm0.rho_initial:=7.5')
    with reaped(proc):
        out, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2, (out, err)
    assert 'rho_initial' in err
    assert 'Traceback' not in err + out


@pytest.mark.parametrize('executor_kind', ['events', 'single'])
def test_process_serves_topics_services_and_parameters(client, executor_kind):
    """main()'s executor serves commands, the reset service and the parameter services."""
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from std_msgs.msg import Float64
    from std_srvs.srv import Trigger

    node, executor = client
    namespace = f'/proc_serve_{executor_kind}_{os.getpid()}'
    states = []
    node.create_subscription(JointState, f'{namespace}/joint_states', states.append, 100)
    pub = node.create_publisher(Float64, f'{namespace}/m0/rho_cmd', 10)
    reset = node.create_client(Trigger, f'{namespace}/tensegrity/reset')
    params = AsyncParameterClient(node, f'{namespace}/tensegrity')
    proc = start_node(namespace, executor=executor_kind)
    with reaped(proc):
        spin_until(node, executor, lambda: states and pub.get_subscription_count() > 0, proc,
                   'discovery')
        pub.publish(Float64(data=0.9))
        spin_until(node, executor, lambda: states[-1].position[0] == 0.9, proc, 'rho 0.9')
        spin_until(node, executor, params.services_are_ready, proc, 'parameter services')
        future = params.set_parameters([Parameter('m0.L1', value='x'),
                                        Parameter('m0.k', value=120.0)])
        spin_until(node, executor, future.done, proc, 'set_parameters')
        first, second = future.result().results
        assert not first.successful and 'type' in first.reason
        assert second.successful, second.reason
        spin_until(node, executor, reset.service_is_ready, proc, 'reset service')
        future = reset.call_async(Trigger.Request())
        spin_until(node, executor, future.done, proc, 'reset')
        assert future.result().success, future.result().message
        spin_until(node, executor, lambda: states[-1].position[0] == 0.75, proc, 'rho 0.75')
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err, err


def handles_sigterm(pid):
    """True once the program handles SIGTERM (Linux: SigCgt in /proc/<pid>/status).

    The interpreter catches SIGINT by itself from the start; SIGTERM is caught only once
    tensegrity_ros.ros.node runs (it installs its start-up handlers before its imports).
    """
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return False
    caught = next(line for line in status.splitlines() if line.startswith('SigCgt:'))
    return bool(int(caught.split()[1], 16) & (1 << (signal.SIGTERM - 1)))


@pytest.mark.skipif(not Path('/proc/self/status').exists(), reason='needs Linux /proc')
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_at_any_time_during_start_up_exits_cleanly(sig):
    """Ctrl-C while importing, initialising or constructing: still exit 0, no traceback.

    From the moment the program runs (its module installs its own handlers; before that the
    Python interpreter itself is starting), the signal may land anywhere in start-up.  The
    extra delays are fault injection, not synchronisation: every outcome must be clean.
    """
    for delay in (0.0, 0.15, 0.3, 0.6):
        proc = start_node(f'/proc_early_{sig.name.lower()}_{os.getpid()}')
        with reaped(proc):
            deadline = time.monotonic() + TIMEOUT
            while not handles_sigterm(proc.pid) and proc.poll() is None:
                assert time.monotonic() < deadline, 'the node never installed its handlers'
                time.sleep(0.001)
            try:
                proc.communicate(timeout=delay or None) if delay else None
            except subprocess.TimeoutExpired:
                pass
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=TIMEOUT)
        assert proc.returncode == 0, (delay, err)
        assert 'Traceback' not in err, (delay, err)
