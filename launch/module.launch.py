"""Start one tensegrity node: ``ros2 launch tensegrity_ros module.launch.py [arg:=value ...]``.

One module on ``config/default.yaml`` unless ``config`` names another parameters file
(any number of modules: ``neck.launch.py`` is this file on ``config/neck.yaml``).
``params`` takes parameter overrides applied after ``config``: one YAML mapping, e.g.
``params:="{m0.rho_initial: 0.8, m0.force_a3: [0.0, 5.0]}"``, or the path of a
parameters file.  ``ros2 launch tensegrity_ros module.launch.py --show-args`` lists every
argument.

Failing loudly: the parameter files go to the node itself (``--params-file``), which
checks them as ``ros2 run`` does (a missing, unreadable or invalid file is one FATAL line
and exit status 2), rather than through launch_ros, which warns "Parameter file path is
not a file" and starts the node without it.  When the node exits the launch shuts down,
and a non-zero exit status ends ``ros2 launch`` with a non-zero status too.  ``log_level``
applies to this node's logger only (not to rcl and the DDS layer underneath).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
import yaml

PACKAGE = 'tensegrity_ros'


class NodeFailed(RuntimeError):
    """The node exited with a non-zero status: ``ros2 launch`` ends with status 1."""


def default_config(name):
    """Path of ``config/<name>`` installed with the package."""
    return os.path.join(get_package_share_directory(PACKAGE), 'config', name)


def yaml_value(context, argument, kinds):
    """The launch argument ``argument`` parsed as YAML; refuse anything but ``kinds``."""
    text = LaunchConfiguration(argument).perform(context)
    value = yaml.safe_load(text) if text.strip() else {}
    if not isinstance(value, kinds):
        names = ' or '.join(k.__name__ for k in kinds)
        raise ValueError(f'launch argument {argument} must be a YAML {names}, got {text!r}')
    return value


def logger_name(namespace, name):
    """The node's logger: its namespace and name joined by dots (rcl's rule)."""
    return '.'.join([part for part in namespace.split('/') if part] + [name])


def exit_status(context):
    """on_exit of the node: the launch shuts down; a failed node fails the launch."""
    code = context.locals.event.returncode
    if code:
        raise NodeFailed(f'tensegrity_node exited with status {code}')
    return [Shutdown(reason='tensegrity_node exited')]


def tensegrity_node(context):
    """The node action, with the launch arguments resolved (overrides after the files)."""
    def text(name):
        return LaunchConfiguration(name).perform(context)
    files = ['--params-file', text('config')]
    overrides = {'use_sim_time': yaml_value(context, 'use_sim_time', (bool,))}
    params = yaml_value(context, 'params', (dict, str))
    if isinstance(params, str):                 # the path of a parameters file
        files += ['--params-file', params]
    else:
        overrides.update(params)
    name, namespace = text('node_name'), text('namespace')
    return [Node(
        package=PACKAGE, executable='tensegrity_node', name=name, namespace=namespace,
        output='screen', parameters=[overrides],
        arguments=['--executor', text('executor')],
        ros_arguments=['--log-level', f'{logger_name(namespace, name)}:={text("log_level")}']
        + files,
        on_exit=[OpaqueFunction(function=exit_status)])]


def arguments(config):
    """The launch arguments, ``config`` defaulting to ``config/<config>`` of the package."""
    return [
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the node and its relative topics'),
        DeclareLaunchArgument('node_name', default_value='tensegrity',
                              description='node name (parameters: ros2 param ... /<ns>/<name>; '
                                          'private topics /<ns>/<name>/...)'),
        DeclareLaunchArgument('config', default_value=default_config(config),
                              description='parameters YAML file (its /** section applies '
                                          'whatever the node name and namespace); a missing '
                                          'or invalid file ends the launch (FATAL)'),
        DeclareLaunchArgument('params', default_value='{}',
                              description='parameter overrides applied after config: one YAML '
                                          'mapping, e.g. "{m0.rho_initial: 0.8}", or the path '
                                          'of a parameters file'),
        DeclareLaunchArgument('use_sim_time', default_value='false', choices=['true', 'false'],
                              description='node clock from /clock: joint_states stamps and '
                                          'speed-limit segments follow simulated time'),
        DeclareLaunchArgument('executor', default_value='events', choices=['events', 'single'],
                              description='rclpy executor: events (fast) or single '
                                          '(SingleThreadedExecutor)'),
        DeclareLaunchArgument('log_level', default_value='info',
                              choices=['debug', 'info', 'warn', 'error', 'fatal'],
                              description="the node's log level (its logger only, not rcl's "
                                          "or the DDS layer's)"),
    ]


def generate_launch_description():
    return LaunchDescription(arguments('default.yaml')
                             + [OpaqueFunction(function=tensegrity_node)])
