"""Broadcast a saved calibration on /tf_static at every start:
``ros2 launch pascal_calib_ros publish.launch.py file:=$HOME/calib/wrist/hand_eye.yaml``.

``file`` is a ``hand_eye.yaml`` (eye in hand: tool -> camera optical frame; eye to hand: base -> camera)
or a ``stereo.yaml`` (left -> right optical frame) written by the calibration node or ``pascal-calib``.
The publisher refuses a file it cannot stand behind (the reason in the log, exit code 2) and broadcasts
again when the file changes, so a recalibration takes effect without a restart.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

# launch argument -> what it sets; each name is a publisher parameter (test/ros/test_launch.py checks)
ARGUMENTS = {
    "file": "the hand_eye.yaml or stereo.yaml to broadcast",
    "watch_period": "seconds between checks of the file (0: read once)",
}
DEFAULTS = {"file": "", "watch_period": "1.0"}


def generate_launch_description():
    args = [DeclareLaunchArgument(name, default_value=DEFAULTS[name], description=what)
            for name, what in ARGUMENTS.items()]
    node = Node(package="pascal_calib_ros", executable="publisher", name="pascal_calib_publisher", output="screen",
                parameters=[{"file": ParameterValue(LaunchConfiguration("file"), value_type=str),
                             "watch_period": ParameterValue(LaunchConfiguration("watch_period"), value_type=float)}])
    return LaunchDescription([*args, node])
