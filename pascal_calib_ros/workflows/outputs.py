"""What a calibration leaves behind, the same from the CLI and the node: the CameraInfo data (K, D,
R = I, P the rectified projection) and one result's files (:func:`write_result_files`): the camera
YAML, its calibration record ``CAM.calibration.json`` (:mod:`..io.calibration_json`, versioned),
with a hand-eye result ``hand_eye.yaml``, on request the report. Where each goes is a
:class:`ResultPaths`: the node's result set (:mod:`.result_set`) puts them in one folder, the CLI
where its options say. The outcomes (:class:`~.intrinsic.IntrinsicOutcome`,
:class:`~.hand_eye.HandEyeOutcome`) write through here."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import Assessment
from ..calibrate import CalibrationResult
from ..detect import Detection
from ..io import (
    CalibrationRecord,
    CameraInfoData,
    HandEyeRecord,
    camera_info_of,
    sidecar_path,
    write_calibration_json,
    write_camera_yaml,
    write_hand_eye_yaml,
)
from ..report import write_report
from .calibration_record import record_of_calibration, record_of_result

HAND_EYE_FILE = "hand_eye.yaml"
ImageSource = Callable[[str], "np.ndarray | None"]  # a view's name -> its grey image (None: not at hand)


def camera_info_data(res: CalibrationResult, camera_name: str) -> CameraInfoData:
    """The CameraInfo of a calibration: its record's (:func:`~..io.camera_yaml.camera_info_of`: K, D,
    its ROS distortion model, R = I and P the rectified projection)."""
    return camera_info_of(record_of_result(res, camera_name))


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


def write_calibration(rec: CalibrationRecord, camera_yaml: str | Path) -> list[Path]:
    """A calibrated camera's two files, both from the one record: the camera_calibration_parsers
    YAML and ``CAM.calibration.json`` beside it (:mod:`..io.calibration_json`: the covariance
    ``pascal-calib verify`` tests against and the observed field ``export --region`` refits over)."""
    yaml_path = write_camera_yaml(camera_yaml, camera_info_of(rec))
    return [yaml_path, write_calibration_json(sidecar_path(yaml_path), rec)]


@dataclass(frozen=True)
class ResultPaths:
    """Where one result's files go: the camera YAML (its record beside it), ``hand_eye.yaml`` (for a
    hand-eye result), the report's folder (None: no report)."""

    camera_yaml: Path
    hand_eye_yaml: Path | None = None
    report_dir: Path | None = None

    @classmethod
    def in_folder(cls, folder: Path, camera_name: str, *, hand_eye: bool = False, report: bool = False
                  ) -> ResultPaths:
        """Every file in ``folder`` under its usual name (a node's result set)."""
        return cls(folder / f"{camera_name}.yaml", folder / HAND_EYE_FILE if hand_eye else None,
                   folder if report else None)


@dataclass(frozen=True)
class ReportRequest:
    """What the report of a result needs besides the result: the views and their images."""

    views: list[Detection]
    images: ImageSource | None


@dataclass
class WrittenFiles:
    """The files one result left, in the order written, and the warnings (a report that failed)."""

    paths: list[Path] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def write_result_files(paths: ResultPaths, a: Assessment, camera_name: str, hand_eye: HandEyeRecord | None = None,
                       report: ReportRequest | None = None, hand_eye_result: Any = None) -> WrittenFiles:
    """One result's files (module docstring): the camera YAML and its record, ``hand_eye.yaml`` when
    ``hand_eye`` is given (``paths.hand_eye_yaml`` must be set), the report when ``paths.report_dir``
    and ``report`` are (``hand_eye_result`` adds its page). A report that fails is a warning: it
    must never cost the calibration."""
    out = WrittenFiles(write_calibration(record_of_calibration(a, camera_name), paths.camera_yaml))
    if hand_eye is not None:
        if paths.hand_eye_yaml is None:
            raise ValueError("a hand-eye result needs paths.hand_eye_yaml")
        write_hand_eye_yaml(paths.hand_eye_yaml, hand_eye)
        out.paths.append(paths.hand_eye_yaml)
    if report is None or paths.report_dir is None:
        return out
    try:
        files = write_report(a, report.views, paths.report_dir, images=report.images, hand_eye=hand_eye_result)
        out.paths += [files.pdf, files.png, files.json]
    except Exception as e:  # a report must never cost the calibration
        out.warnings.append(f"report not written: {type(e).__name__}: {e}")
    return out


# an outcome's ``write(paths, camera_name, report)``: how the node and the CLI hand it their paths
ResultWriter = Callable[[ResultPaths, str, "ReportRequest | None"], WrittenFiles]
