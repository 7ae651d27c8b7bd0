"""Files and messages: images and sensor_msgs encodings (without cv_bridge), camera and hand-eye
YAML, robot pose files, rosbag2 bags, printable targets, what is read back from a report.json.
Imports nothing above :mod:`..detect`."""

from .camera_yaml import CameraInfoData, CameraYamlError, read_camera_yaml, write_camera_yaml
from .hand_eye_yaml import HandEyeRecord, PosesYamlError, read_hand_eye_yaml, read_poses_yaml, write_hand_eye_yaml
from .image_msgs import ImageConversionError, compressed_to_grey, image_to_grey
from .images import ImageReadError, expand_image_args, read_grey

__all__ = ["CameraInfoData", "CameraYamlError", "HandEyeRecord", "ImageConversionError", "ImageReadError",
           "PosesYamlError", "compressed_to_grey", "expand_image_args", "image_to_grey", "read_camera_yaml",
           "read_grey", "read_hand_eye_yaml", "read_poses_yaml", "write_camera_yaml", "write_hand_eye_yaml"]
