"""Start one tensegrity node: ``ros2 launch tensegrity_ros module.launch.py [arg:=value ...]``.

One module on ``config/default.yaml`` unless ``config`` names another parameters file
(any number of modules: ``neck.launch.py`` is this file on ``config/neck.yaml``).
``params`` takes parameter overrides as one YAML mapping, applied after ``config``, e.g.
``params:="{m0.rho_initial: 0.8, m0.force_a3: [0.0, 5.0]}"``.
``ros2 launch tensegrity_ros module.launch.py --show-args`` lists every argument.
"""
import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'tensegrity_ros'


def default_config(name):
    """Path of ``config/<name>`` installed with the package."""
    return os.path.join(get_package_share_directory(PACKAGE), 'config', name)


def yaml_value(context, argument, kind):
    """The launch argument ``argument`` parsed as YAML; refuse anything but a ``kind``."""
    text = LaunchConfiguration(argument).perform(context)
    value = yaml.safe_load(text) if text.strip() else None
    if kind is dict and value is None:
        value = {}
    if not isinstance(value, kind):
        raise ValueError(f'launch argument {argument} must be a YAML {kind.__name__}, '
                         f'got {text!r}')
    return value


def tensegrity_node(context):
    """The node action, with the launch arguments resolved (overrides after the file)."""
    def text(name):
        return LaunchConfiguration(name).perform(context)
    overrides = {'use_sim_time': yaml_value(context, 'use_sim_time', bool)}
    overrides.update(yaml_value(context, 'params', dict))
    return [Node(
        package=PACKAGE, executable='tensegrity_node', name=text('node_name'),
        namespace=text('namespace'), output='screen',
        parameters=[text('config'), overrides],
        arguments=['--executor', text('executor')],
        ros_arguments=['--log-level', text('log_level')])]


def arguments(config):
    """The launch arguments, ``config`` defaulting to ``config/<config>`` of the package."""
    return [
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the node and its relative topics'),
        DeclareLaunchArgument('node_name', default_value='tensegrity',
                              description='node name (parameters: ros2 param ... /<ns>/<name>)'),
        DeclareLaunchArgument('config', default_value=default_config(config),
                              description='parameters YAML file (its /** section applies '
                                          'whatever the node name and namespace)'),
        DeclareLaunchArgument('params', default_value='{}',
                              description='parameter overrides, one YAML mapping applied after '
                                          'config, e.g. "{m0.rho_initial: 0.8}"'),
        DeclareLaunchArgument('use_sim_time', default_value='false', choices=['true', 'false'],
                              description='node clock from /clock: joint_states stamps and '
                                          'speed-limit segments follow simulated time'),
        DeclareLaunchArgument('executor', default_value='events', choices=['events', 'single'],
                              description='rclpy executor: events (fast) or single '
                                          '(SingleThreadedExecutor)'),
        DeclareLaunchArgument('log_level', default_value='info',
                              choices=['debug', 'info', 'warn', 'error', 'fatal'],
                              description='node log level'),
    ]


def generate_launch_description():
    return LaunchDescription(arguments('default.yaml')
                             + [OpaqueFunction(function=tensegrity_node)])
