"""What the CLI and the node both do, written once: detect, run an intrinsic or a hand-eye
calibration and assess it (an outcome with ``camera_info`` and ``write``), one result's files
(the camera YAML, its calibration record, hand_eye.yaml, the report) and the lines a person reads."""

from .calibration_record import intrinsic_covariance, record_of_result
from .detection import detect_files, detect_images, detection_params
from .export import FORMATS, ExportRequest, export_calibration
from .hand_eye import HandEyeFrames, HandEyeOutcome, hand_eye_doubts, hand_eye_frames, run_hand_eye
from .intrinsic import IntrinsicOutcome, run_intrinsic
from .outputs import (
    HAND_EYE_FILE,
    ReportRequest,
    ResultPaths,
    ResultWriter,
    WrittenFiles,
    calibration_file_path,
    camera_info_data,
    output_folder,
    write_calibration,
    write_result_files,
)
from .result_set import ResultSet, ResultStore, copy_atomic
from .static_transform import ResultFileError, StaticTransform, read_result_transforms
from .stereo import (
    PairingError,
    StereoOptions,
    StereoOutcome,
    expand_glob,
    pair_files,
    run_rig,
    run_stereo,
    write_reports,
)
from .stereo_session import (
    StereoSessionOptions,
    answer_line,
    calibrate_stereo_session,
    recorded_stereo_shots,
    run_recorded_stereo,
    stereo_output_dir,
    write_session_report,
)
from .suggest import SuggestError, SuggestOptions, WarmArmSuggestions, suggest_for_arm, suggest_for_person, summary
from .verify import VerifyRequest, hand_eye_reference_of_result, reference_of_file, run_verify, verify_detections

__all__ = ["FORMATS", "HAND_EYE_FILE", "ExportRequest", "HandEyeFrames", "HandEyeOutcome", "IntrinsicOutcome",
           "PairingError", "ReportRequest", "ResultFileError", "ResultPaths", "ResultSet", "ResultStore",
           "ResultWriter", "StaticTransform", "StereoOptions", "StereoOutcome", "StereoSessionOptions",
           "SuggestError", "SuggestOptions", "VerifyRequest", "WarmArmSuggestions", "WrittenFiles", "answer_line",
           "calibrate_stereo_session", "calibration_file_path", "camera_info_data", "copy_atomic", "detect_files",
           "detect_images", "detection_params", "expand_glob", "export_calibration", "hand_eye_doubts",
           "hand_eye_frames", "hand_eye_reference_of_result", "intrinsic_covariance", "output_folder", "pair_files",
           "read_result_transforms", "record_of_result", "recorded_stereo_shots", "reference_of_file", "run_hand_eye",
           "run_intrinsic", "run_recorded_stereo", "run_rig", "run_stereo", "run_verify", "stereo_output_dir",
           "suggest_for_arm", "suggest_for_person", "summary", "verify_detections", "write_calibration",
           "write_reports", "write_result_files", "write_session_report"]
