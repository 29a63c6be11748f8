"""Launches chronomap's ROS 2 node as any ROS 2 node, with launch_ros.

    ros2 launch chronomap.launch.py                  # the node, configured and active
    ros2 launch chronomap.launch.py managed:=true    # managed by nav2_lifecycle_manager

`chronomap` must be on PATH (the node is not a ROS package: `package` is left out, so
launch_ros runs the executable found on PATH). launch_ros passes the name, namespace,
parameters and remappings as ROS arguments: `chronomap ros2 --ros-args -r __node:=chronomap
-r __ns:=/robot1 --params-file chronomap.yaml --params-file /tmp/launch_params_... -r
/door:=/front_door/open`.

Managed, the node starts unconfigured; nav2_lifecycle_manager configures and activates it
(`autostart`), and deactivates, cleans it up and shuts it down with the rest of the stack. The
node does not take part in bond heartbeats: `bond_timeout: 0.0` tells the manager not to wait
for them. See docs/ros2.md.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = os.path.dirname(os.path.abspath(__file__))


def generate_launch_description():
    managed = LaunchConfiguration('managed')
    parameters = [os.path.join(HERE, 'chronomap.yaml'), {'horizon': 600.0}]
    remappings = [('/door', '/front_door/open')]
    return LaunchDescription([
        DeclareLaunchArgument('managed', default_value='false',
                              description='run chronomap as a managed (lifecycle) node'),
        Node(
            executable='chronomap',
            arguments=['ros2'],
            name='chronomap',
            namespace='robot1',
            parameters=parameters,
            remappings=remappings,
            output='screen',
            condition=UnlessCondition(managed),
        ),
        Node(
            executable='chronomap',
            arguments=['ros2', '--managed'],
            name='chronomap',
            namespace='robot1',
            parameters=parameters,
            remappings=remappings,
            output='screen',
            condition=IfCondition(managed),
        ),
        Node(
            package='nav2_lifecycle_manager',
            executable='lifecycle_manager',
            name='lifecycle_manager_chronomap',
            namespace='robot1',
            parameters=[{
                'autostart': True,
                'node_names': ['chronomap'],
                'bond_timeout': 0.0,
            }],
            output='screen',
            condition=IfCondition(managed),
        ),
    ])
