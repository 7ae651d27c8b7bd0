"""What the CLI and the node both do, written once: detect, run an intrinsic or a hand-eye
calibration and assess it, make every output (CameraInfo data, YAMLs, calibration.json, report)
and the lines a person reads."""

from .detection import detect_files, detect_images, detection_params
from .hand_eye import HandEyeOutcome, hand_eye_doubts, hand_eye_frames, run_hand_eye, static_transform_command
from .intrinsic import IntrinsicOutcome, run_intrinsic
from .outputs import calibration_file_path, camera_info_data, write_camera_file, write_session_files

__all__ = ["HandEyeOutcome", "IntrinsicOutcome", "calibration_file_path", "camera_info_data", "detect_files",
           "detect_images", "detection_params", "hand_eye_doubts", "hand_eye_frames", "run_hand_eye", "run_intrinsic",
           "static_transform_command", "write_camera_file", "write_session_files"]
