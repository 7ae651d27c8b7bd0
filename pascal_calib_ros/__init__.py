"""pascal_calib_ros: camera calibration from printed circular targets (and checkerboards), with
honest uncertainty, for ROS 2.

Layers, lowest first (each imports only those below it): :mod:`.geometry` -> :mod:`.detect` ->
:mod:`.io` -> :mod:`.calibrate` -> :mod:`.analysis` -> :mod:`.session`, :mod:`.report` ->
:mod:`.workflows` -> :mod:`.cli`, :mod:`.ros`; :mod:`.sim` and :mod:`.studies` beside them. The
names below are loaded on first use (the calibration itself: :func:`.calibrate.calibrate`).
"""

from __future__ import annotations

import importlib
from typing import Any

_API = {
    "PascalCalibError": "errors", "Target": "targets", "TargetError": "targets", "resolve_target": "targets",
    "load_target": "targets", "Camera": "geometry.camera", "Transform": "geometry.transform",
    "Detection": "detect.detection", "DetectionParams": "detect.detection", "detect_target": "detect.target_detector",
    "CalibrationOptions": "calibrate.options", "CalibrationResult": "calibrate.result",
    "CalibrationError": "calibrate.result", "HandEyeOptions": "calibrate.handeye", "HandEyeResult": "calibrate.handeye",
    "calibrate_hand_eye": "calibrate.handeye", "Assessment": "analysis.assessment",
    "assess": "analysis.assessment", "run_intrinsic": "workflows.intrinsic", "run_hand_eye": "workflows.hand_eye",
}
__all__ = sorted(_API)


def __getattr__(name: str) -> Any:
    if name in _API:
        return getattr(importlib.import_module(f".{_API[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
