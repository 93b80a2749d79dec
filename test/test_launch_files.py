"""The launch files in launch/ (``ros2 launch tensegrity_ros module.launch.py | neck.launch.py``).

The project's own environment has no ``launch`` (it is not in requirements.txt): there the
files are checked as Python source, that they declare the arguments README documents.  In a
ROS environment (``colcon test``, see docs/development.md) the installed neck launch file is
also run for real with every argument set, and what comes up is asked over ROS.
"""
import ast
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_DIR = ROOT / 'launch'
README = ROOT / 'README.md'
ARGUMENTS = {'namespace', 'node_name', 'config', 'params', 'use_sim_time', 'executor',
             'log_level'}
TIMEOUT = float(os.environ.get('TENSEGRITY_TEST_TIMEOUT', '30'))


def declared_arguments(path):
    """Names given to ``DeclareLaunchArgument(...)`` in a launch file, from its syntax tree."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return {call.args[0].value for call in ast.walk(tree)
            if isinstance(call, ast.Call)
            and getattr(call.func, 'id', '') == 'DeclareLaunchArgument'
            and call.args and isinstance(call.args[0], ast.Constant)}


def test_module_launch_file_declares_the_documented_arguments():
    declared = declared_arguments(LAUNCH_DIR / 'module.launch.py')
    assert declared == ARGUMENTS
    readme = README.read_text()
    assert 'ros2 launch tensegrity_ros module.launch.py' in readme
    for name in ARGUMENTS:
        assert f'`{name}`' in readme, f'launch argument {name} is not documented in README.md'


def test_neck_launch_file_is_the_module_one_on_the_neck_config():
    path = LAUNCH_DIR / 'neck.launch.py'
    assert declared_arguments(path) == {'config'}
    source = path.read_text()
    assert "'module.launch.py'" in source and "'neck.yaml'" in source
    assert 'ros2 launch tensegrity_ros neck.launch.py' in README.read_text()


def test_every_launch_file_has_a_launch_description():
    files = sorted(LAUNCH_DIR.glob('*.launch.py'))
    assert [f.name for f in files] == ['module.launch.py', 'neck.launch.py']
    for path in files:
        tree = ast.parse(path.read_text(), filename=str(path))
        names = {f.name for f in tree.body if isinstance(f, ast.FunctionDef)}
        assert 'generate_launch_description' in names, path


# Runs a launch file the way ``ros2 launch <file> name:=value ...`` does.  launch sees SIGINT
# through Python's handler: restore it in case this process was started with SIGINT ignored.
LAUNCHER = """
import signal
import sys
signal.signal(signal.SIGINT, signal.default_int_handler)
from launch import LaunchService
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
arguments = [tuple(a.split(':=', 1)) for a in sys.argv[2:]]
service = LaunchService()
service.include_launch_description(IncludeLaunchDescription(
    PythonLaunchDescriptionSource(sys.argv[1]), launch_arguments=arguments))
sys.exit(service.run())
"""


@pytest.mark.ros
def test_a_parameter_file_as_launch_ros_writes_it_is_read(tmp_path):
    """launch_ros writes a launch file's parameter dictionary with ``yaml.dump`` after
    turning lists into tuples (``!!python/tuple``); rcl reads that, so the node's own
    check must too (it refused it: "could not determine a constructor", exit 2)."""
    import yaml

    from tensegrity_ros.params_file import check_parameter_file, load_stack_config
    path = tmp_path / 'launch_params.yaml'
    path.write_text(yaml.dump({'/**': {'ros__parameters': {
        'modules': ('m0', 'm1'), 'm0.force_a3': (0.0, -1.0), 'm1.rho_initial': 0.8}}}))
    assert '!!python/tuple' in path.read_text()
    check_parameter_file(str(path))
    config = load_stack_config(str(path))
    assert [m.name for m in config.modules] == ['m0', 'm1']
    assert (config.modules[0].params.f3x, config.modules[0].params.f3y) == (0.0, -1.0)


def test_installed_neck_launch_file_starts_the_node_with_every_argument():
    pytest.importorskip('launch_ros', reason='no launch_ros here (not in requirements.txt): this '
                        'test runs under colcon test in a ROS environment (docs/development.md)')
    from ament_index_python.packages import get_package_share_directory
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Bool

    share = Path(get_package_share_directory('tensegrity_ros'))
    launch_file = share / 'launch' / 'neck.launch.py'
    assert os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
    proc = subprocess.Popen(
        [sys.executable, '-c', LAUNCHER, str(launch_file), 'namespace:=launched',
         'node_name:=bird_neck', 'params:={m0.rho_initial: 0.1, m2.force_a3: [0.0, -1.0]}',
         'use_sim_time:=true', 'executor:=single', 'log_level:=warn'],
        env=dict(os.environ, PYTHONUNBUFFERED='1'), start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('launch_test_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        stable = []
        node.create_subscription(Bool, '/launched/bird_neck/stable',
                                 lambda msg: stable.append(msg.data), latched)
        parameters = AsyncParameterClient(node, '/launched/bird_neck')
        spin_until(executor, proc, lambda: bool(stable), 'the latched /launched/bird_neck/stable')
        future = parameters.get_parameters(['modules', 'm0.rho_initial', 'm2.force_a3',
                                            'm1.k', 'use_sim_time'])
        spin_until(executor, proc, future.done, "the node's parameters")
        values = [rclpy.parameter.parameter_value_to_python(v) for v in future.result().values]
        assert stable == [True]
        assert values[0] == ['m0', 'm1', 'm2']             # config/neck.yaml
        assert values[1] == pytest.approx(0.1)              # params override
        assert list(values[2]) == pytest.approx([0.0, -1.0])
        assert values[3] == pytest.approx(300.0)            # from neck.yaml, not overridden
        assert values[4] is True                            # use_sim_time
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            out, _ = proc.communicate(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:   # end the launch and the node it started
            os.killpg(proc.pid, signal.SIGKILL)
            out, _ = proc.communicate()
    assert proc.returncode == 0, out
    assert 'process has finished cleanly' in out, out


def run_launch(*arguments, launch_file='module.launch.py'):
    """Run an installed launch file to its end: (exit status, output)."""
    from ament_index_python.packages import get_package_share_directory
    path = Path(get_package_share_directory('tensegrity_ros')) / 'launch' / launch_file
    proc = subprocess.run([sys.executable, '-c', LAUNCHER, str(path), *arguments],
                          env=dict(os.environ, PYTHONUNBUFFERED='1'), start_new_session=True,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=TIMEOUT)
    return proc.returncode, proc.stdout


@pytest.mark.parametrize('launch_file, argument', [
    ('module.launch.py', 'config:=/no/such.yaml'),
    ('neck.launch.py', 'config:=/no/such.yaml'),
    ('module.launch.py', 'params:=/no/such/overrides.yaml'),
])
def test_a_missing_parameter_file_ends_the_launch_with_one_fatal_line(launch_file, argument):
    """launch_ros would warn "Parameter file path is not a file" and start the default node:
    the node gets the files itself, says FATAL once and exits 2, and the launch fails."""
    pytest.importorskip('launch_ros', reason='no launch_ros here (not in requirements.txt): '
                        'this test runs under colcon test in a ROS environment')
    code, out = run_launch(argument, launch_file=launch_file)
    fatal = [line for line in out.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and 'cannot read /no/such' in fatal[0], out
    assert 'exit code 2' in out and code != 0, out
    assert 'Parameter file path is not a file' not in out, out


def test_the_log_level_argument_is_the_nodes_only(tmp_path):
    """log_level:=debug reaches the node's logger (<ns>.<name>) and not rcl's: before, it
    was global (37,730 rcl lines in 2 min)."""
    pytest.importorskip('launch_ros', reason='no launch_ros here (not in requirements.txt): '
                        'this test runs under colcon test in a ROS environment')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    m0.L1: -1.0\n')
    # a configuration the node refuses: it starts, logs and exits 2 at once
    code, out = run_launch('namespace:=/a/b', 'node_name:=nb', 'log_level:=debug',
                           f'params:={bad}')
    assert code != 0 and 'm0.L1 must be finite and > 0' in out, out
    assert '--log-level a.b.nb:=debug' in out, out
    assert not [line for line in out.splitlines() if '[DEBUG]' in line and '[rcl' in line], out


def spin_until(executor, proc, predicate, what):
    """Spin until ``predicate()``; fail naming ``what`` if the launch exits or time runs out."""
    deadline = time.monotonic() + TIMEOUT
    while not predicate():
        if proc.poll() is not None:
            raise AssertionError(f'launch exited ({proc.returncode}) waiting for {what}:\n'
                                 f'{proc.communicate()[0]}')
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        executor.spin_once(timeout_sec=0.05)
