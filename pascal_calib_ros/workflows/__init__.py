"""What the CLI and the node both do, written once: detect, run an intrinsic or a hand-eye
calibration and assess it (an outcome with ``camera_info`` and ``write``), one result's files
(the camera YAML, its calibration record, hand_eye.yaml, the report) and the lines a person reads."""

from .detection import detect_files, detect_images, detection_params
from .hand_eye import (
    HandEyeFrames,
    HandEyeOutcome,
    hand_eye_doubts,
    hand_eye_frames,
    run_hand_eye,
)
from .intrinsic import IntrinsicOutcome, run_intrinsic
from .outputs import (
    ReportRequest,
    ResultPaths,
    WrittenFiles,
    calibration_file_path,
    camera_info_data,
    write_result_files,
)

__all__ = ["HandEyeFrames", "HandEyeOutcome", "IntrinsicOutcome", "ReportRequest", "ResultPaths", "WrittenFiles",
           "calibration_file_path", "camera_info_data", "detect_files", "detect_images", "detection_params",
           "hand_eye_doubts", "hand_eye_frames", "run_hand_eye", "run_intrinsic",
           "write_result_files"]
