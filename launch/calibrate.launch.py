"""Start the calibration node: ``ros2 launch pascal_calib_ros calibrate.launch.py image:=/camera/image_raw``.

Mono (``mode:=mono``, the default), a stereo pair (``mode:=stereo left_image:=... right_image:=...``) or a
robot arm (``hand_eye:=eye_in_hand robot_pose_topic:=/tcp_pose collect:=on_capture``). Every node parameter
comes from ``params_file`` (default: the packaged ``config/calibration_node.yaml``); an argument in
ARGUMENTS overrides its parameter only when given (empty: the params file's value). After a hand-eye or
stereo ``~/calibrate`` the node broadcasts the transform on /tf_static; ``publish.launch.py`` broadcasts the
saved result at every later start.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

# launch argument -> what it sets; each name is a calibration_node parameter (test/ros/test_launch.py checks)
ARGUMENTS = {
    "mode": "mono | stereo",
    "target": "target YAML path or packaged target name (ring_a4, ring_grid_a4, checkerboard_a4, ...)",
    "camera_name": "camera_name of the YAML and CameraInfo (stereo: NAME/left, NAME/right)",
    "output_dir": "where the result sets (the YAML, hand_eye.yaml / stereo.yaml, the report) and sessions go",
    "session_dir": "the session folder (every stored view written as it is taken)",
    "resume": "true: continue the views of session_dir (or the newest session) after a crash",
    "distortion_model": "plumb_bob | rational_polynomial | equidistant | ...",
    "gamma": "display gamma of the camera (1 linear, about 2.2 sRGB webcams)",
    "transport": "raw | compressed",
    "set_camera_info_service": "the driver's sensor_msgs/SetCameraInfo service (~/commit)",
    "collect": "auto | on_capture (robot arms: only ~/capture stores views)",
    "robot_pose_topic": "geometry_msgs/PoseStamped or TransformStamped of the tool in the robot base",
    "hand_eye": "eye_in_hand | eye_to_hand: ~/calibrate also solves the hand-eye transform",
    "robot_base_frame": "the robot base frame",
    "robot_tool_frame": "the robot tool (flange) frame",
    "camera_frame": "the camera optical frame (child of the hand-eye transform)",
    "left_frame": "stereo: the left camera's optical frame",
    "right_frame": "stereo: the right camera's optical frame",
}
# launch argument -> the node's topic it remaps
REMAPS = {"image": "image", "left_image": "left/image", "right_image": "right/image"}


def _node(context, *args, **kwargs):
    from pascal_calib_ros.ros.params import PARAMS

    kinds = {p.name: type(p.default) for p in PARAMS}
    overrides = {}
    for name in ARGUMENTS:
        value = LaunchConfiguration(name).perform(context)
        if value != "":
            kind = kinds[name]
            overrides[name] = (value.lower() in ("true", "1", "yes")) if kind is bool else kind(value)
    remaps = [(topic, LaunchConfiguration(arg).perform(context)) for arg, topic in REMAPS.items()
              if LaunchConfiguration(arg).perform(context)]
    return [Node(package="pascal_calib_ros", executable="calibration_node", name="pascal_calib", output="screen",
                 parameters=[LaunchConfiguration("params_file").perform(context), overrides], remappings=remaps)]


def generate_launch_description():
    config = os.path.join(get_package_share_directory("pascal_calib_ros"), "config", "calibration_node.yaml")
    args = [DeclareLaunchArgument("params_file", default_value=config, description="the node's parameter file")]
    args += [DeclareLaunchArgument(name, default_value="", description=f"{what} (empty: from params_file)")
             for name, what in ARGUMENTS.items()]
    args += [DeclareLaunchArgument(name, default_value="", description=f"remap the node's {topic} to this topic")
             for name, topic in REMAPS.items()]
    return LaunchDescription([*args, OpaqueFunction(function=_node)])
