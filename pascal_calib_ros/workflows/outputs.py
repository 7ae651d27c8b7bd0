"""What a calibration leaves behind, the same from the CLI and the node: the CameraInfo data (K, D,
R = I, P the rectified projection), the camera YAML, ``calibration.json`` and the report."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.assessment import Assessment
from ..calibrate.result import CalibrationResult
from ..detect.detection import Detection
from ..geometry.camera import rectified_projection
from ..io.calibration_json import sidecar_path, write_calibration_json
from ..io.camera_yaml import CameraInfoData, write_camera_yaml
from ..io.hand_eye_yaml import HandEyeRecord, write_hand_eye_yaml
from ..report.pages import ReportFiles, write_report
from ..report.text import summary_line
from .calibration_record import record_of_calibration

HAND_EYE_FILE = "hand_eye.yaml"
ImageSource = Callable[[str], "np.ndarray | None"]  # a view's name -> its grey image (None: not at hand)


def camera_info_data(res: CalibrationResult, camera_name: str) -> CameraInfoData:
    """The CameraInfo of a calibration: K, D, its ROS distortion model, R = I and P the rectified
    projection (:func:`~..geometry.camera.rectified_projection`: [K 0] for pinhole models)."""
    return CameraInfoData(res.width, res.height, camera_name, res.K, res.D, res.model,
                          P=rectified_projection(res.camera()))


def output_folder(camera_name: str, output_dir: str = "") -> Path:
    """Where a node's results and sessions go: ``output_dir``, else ``~/.ros/pascal_calib/<camera_name>``
    (never the driver's ``~/.ros/camera_info/``: that file changes only through ``~/commit``)."""
    if output_dir:
        return Path(output_dir).expanduser()
    return Path.home() / ".ros" / "pascal_calib" / camera_name


def calibration_file_path(camera_name: str, output_dir: str = "", calibration_file: str = "") -> Path:
    """The camera YAML a node reads back: ``calibration_file``, else ``<output folder>/<camera_name>.yaml``
    (:func:`output_folder`; a link to the current result set, :mod:`.result_set`)."""
    if calibration_file:
        return Path(calibration_file).expanduser()
    return output_folder(camera_name, output_dir) / f"{camera_name}.yaml"


def write_camera_file(res: CalibrationResult, path: str | Path, camera_name: str) -> Path:
    """The camera_calibration_parsers YAML of a calibration."""
    return write_camera_yaml(path, camera_info_data(res, camera_name))


def calibration_json(res: CalibrationResult) -> dict[str, Any]:
    """``calibration.json``: the summary line, K, D, their sigmas, RMS, degeneracy, warnings, the
    target shape and every view's fate."""
    return {"summary": summary_line(res), "K": res.K.tolist(), "D": res.D.tolist(), "std": res.std,
            "rms": res.rms, "degeneracy_ratio": res.degeneracy_ratio, "warnings": res.warnings,
            "target_shape": res.shape, "target_shape_std": res.shape_std,
            "views": [{"name": v.name, "used": v.used, "reason": v.reason, "rms": v.rms} for v in res.views]}


def write_session_files(a: Assessment, dets: list[Detection], out_dir: str | Path, images: ImageSource | None,
                        hand_eye: Any = None) -> ReportFiles:
    """``calibration.json`` and the report (``report.pdf``, ``.png``, ``.json``) in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "calibration.json").write_text(json.dumps(calibration_json(a.result), indent=1, default=float))
    return write_report(a, dets, out, images=images, hand_eye=hand_eye)


def write_calibration_record(a: Assessment, camera_yaml: str | Path, camera_name: str) -> Path:
    """``CAM.calibration.json`` beside the camera YAML (:mod:`..io.calibration_json`): the covariance
    ``pascal-calib verify`` tests against and the observed field ``export --region`` refits over."""
    return write_calibration_json(sidecar_path(camera_yaml), record_of_calibration(a, camera_name))


def write_result_files(folder: Path, a: Assessment, camera_name: str, hand_eye: HandEyeRecord | None = None,
                       report: ReportRequest | None = None) -> list[str]:
    """One result's files in ``folder`` (a result set's staging folder, :mod:`.result_set`): the camera
    YAML, its calibration record, ``hand_eye.yaml`` and, on request, ``calibration.json`` and the
    report. Returns the warnings (a report that failed: it must never cost the calibration)."""
    path = write_camera_file(a.result, folder / f"{camera_name}.yaml", camera_name)
    write_calibration_record(a, path, camera_name)
    if hand_eye is not None:
        write_hand_eye_yaml(folder / HAND_EYE_FILE, hand_eye)
    if report is None:
        return []
    try:
        write_session_files(a, report.views, folder, report.images, hand_eye=report.hand_eye)
    except Exception as e:  # a report must never cost the calibration
        return [f"report not written: {type(e).__name__}: {e}"]
    return []


@dataclass(frozen=True)
class ReportRequest:
    """What the report of a result needs: the views, their images, the hand-eye result if any."""

    views: list[Detection]
    images: ImageSource | None
    hand_eye: Any = None
