"""Start the three-module bird neck: ``ros2 launch tensegrity_ros neck.launch.py [arg:=v ...]``.

``module.launch.py`` on ``config/neck.yaml`` (modules m0, m1, m2, bottom to top): the same
arguments (namespace, node_name, config, params, use_sim_time, executor, log_level), e.g.
``params:="{m2.force_a3: [0.0, -1.0], m2.force_a4: [0.0, -1.0]}"`` for a heavier head.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration


def generate_launch_description():
    neck = os.path.join(get_package_share_directory('tensegrity_ros'), 'config', 'neck.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('config', default_value=neck,
                              description='parameters YAML file of the neck'),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(os.path.dirname(__file__), 'module.launch.py')),
            launch_arguments={'config': LaunchConfiguration('config')}.items()),
    ])
