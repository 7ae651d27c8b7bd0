"""Files and messages: images and sensor_msgs encodings (without cv_bridge), camera and hand-eye
YAML, robot pose files, rosbag2 bags, printable targets, what is read back from a report.json.
Imports nothing above :mod:`..detect`."""

from .atomic import FileWriteError, fsync_folder, replace_symlink, write_bytes_atomic
from .bags import (
    COMPRESSED_TYPE,
    POSE_TYPE,
    BagError,
    BagImage,
    BagPose,
    image_topics,
    pose_topics,
    read_session,
    write_arm_bag,
    write_image_bag,
)
from .calibration_files import CalibrationFile, read_calibration_file
from .calibration_json import CalibrationRecord, sidecar_path, write_calibration_json
from .camera_yaml import CameraInfoData, CameraYamlError, camera_info_of, read_camera_yaml, write_camera_yaml
from .format_error import CalibrationFileError
from .hand_eye_export import static_transform_text, urdf_joint_text
from .hand_eye_yaml import HandEyeRecord, PosesYamlError, read_hand_eye_yaml, read_poses_yaml, write_hand_eye_yaml
from .image_msgs import ImageConversionError, compressed_to_grey, grey_to_image_fields, image_to_grey
from .images import IMAGE_SUFFIXES, ImageReadError, ImageWriteError, expand_image_args, read_grey, write_image
from .kalibr_camchain import KalibrCamera, kalibr_distortion, write_kalibr_camchain
from .mrcal_model import MrcalModel, mrcal_model_of_camera, write_mrcal_model
from .mrcal_splined import SplinedCamera, SplinedModel, design_matrix, splined_camera, stereographic
from .next_yaml import (
    ArmProgress,
    NextYamlError,
    Suggestion,
    Suggestions,
    ToolSuggestion,
    read_next_yaml,
    write_next_yaml,
)
from .opencv_storage import write_opencv_storage
from .printable import write_printable
from .report_json import ReportJsonError, read_view_hulls
from .session_folder import SessionFolder, SessionFolderError, SessionManifest, is_session_folder
from .stereo_bags import read_image_topics, write_stereo_bag
from .stereo_yaml import (
    RigCameraData,
    StereoData,
    StereoYamlError,
    pair_camera_infos,
    read_rig_yaml,
    read_stereo_yaml,
    static_transform_command,
    write_pair_yamls,
    write_rig_yaml,
    write_stereo_yaml,
)

__all__ = ["COMPRESSED_TYPE", "IMAGE_SUFFIXES", "POSE_TYPE", "ArmProgress", "BagError", "BagImage", "BagPose",
           "CalibrationFile", "CalibrationFileError", "CalibrationRecord", "CameraInfoData", "CameraYamlError",
           "FileWriteError", "HandEyeRecord", "ImageConversionError", "ImageReadError", "ImageWriteError",
           "KalibrCamera", "MrcalModel", "NextYamlError", "PosesYamlError", "ReportJsonError", "RigCameraData",
           "SessionFolder", "SessionFolderError", "SessionManifest", "SplinedCamera", "SplinedModel", "StereoData",
           "StereoYamlError", "Suggestion", "Suggestions", "ToolSuggestion", "camera_info_of", "compressed_to_grey",
           "design_matrix", "expand_image_args", "fsync_folder", "grey_to_image_fields", "image_to_grey",
           "image_topics", "is_session_folder", "kalibr_distortion", "mrcal_model_of_camera", "pair_camera_infos",
           "pose_topics", "read_calibration_file", "read_camera_yaml", "read_grey", "read_hand_eye_yaml",
           "read_image_topics", "read_next_yaml", "read_poses_yaml", "read_rig_yaml", "read_session",
           "read_stereo_yaml", "read_view_hulls", "replace_symlink", "sidecar_path", "splined_camera",
           "static_transform_command", "static_transform_text", "stereographic", "urdf_joint_text", "write_arm_bag",
           "write_bytes_atomic", "write_calibration_json", "write_camera_yaml", "write_hand_eye_yaml", "write_image",
           "write_image_bag", "write_kalibr_camchain", "write_mrcal_model", "write_next_yaml", "write_opencv_storage",
           "write_pair_yamls", "write_printable", "write_rig_yaml", "write_stereo_bag", "write_stereo_yaml"]
