"""Read and write the ROS ``camera_calibration_parsers`` YAML (the format of camera_info_manager).

Layout (monocular): image_width, image_height, camera_name, camera_matrix, distortion_model,
distortion_coefficients, rectification_matrix (identity), projection_matrix (P = [K | 0]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError
from ..geometry import ImageSize, rectified_projection
from .atomic import write_text_atomic
from .calibration_json import CalibrationRecord


class CameraYamlError(PascalCalibError):
    """The file is not a camera_calibration_parsers YAML."""


@dataclass(frozen=True)
class CameraInfoData:
    width: int
    height: int
    camera_name: str
    K: np.ndarray
    D: np.ndarray
    distortion_model: str = "plumb_bob"
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    P: np.ndarray | None = None

    @property
    def projection(self) -> np.ndarray:
        """P for a monocular camera: [K | 0]."""
        if self.P is not None:
            return self.P
        return np.concatenate([self.K, np.zeros((3, 1))], 1)

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def camera_info_of(rec: CalibrationRecord, R: np.ndarray | None = None, P: np.ndarray | None = None
                   ) -> CameraInfoData:
    """The CameraInfo of a calibrated camera: its K, D and ROS distortion model; R the rectifying
    rotation (I for a single camera) and P the rectified projection (a pair's P1 / P2; else
    :func:`~..geometry.camera.rectified_projection`: [K | 0] for pinhole models)."""
    cam = rec.camera
    return CameraInfoData(cam.width, cam.height, rec.camera_name, cam.K, np.asarray(cam.D, float), cam.model,
                          np.eye(3) if R is None else R, rectified_projection(cam) if P is None else P)


def _matrix(rows: int, cols: int, data: np.ndarray) -> dict[str, Any]:
    return {"rows": rows, "cols": cols, "data": [float(v) for v in np.asarray(data, float).ravel()]}


def to_yaml_text(info: CameraInfoData) -> str:
    doc = {
        "image_width": int(info.width),
        "image_height": int(info.height),
        "camera_name": info.camera_name,
        "camera_matrix": _matrix(3, 3, info.K),
        "distortion_model": info.distortion_model,
        "distortion_coefficients": _matrix(1, len(info.D), info.D),
        "rectification_matrix": _matrix(3, 3, info.R),
        "projection_matrix": _matrix(3, 4, info.projection),
    }
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def write_camera_yaml(path: str | Path, info: CameraInfoData) -> Path:
    """Write atomically (:mod:`.atomic`), so a reader never sees half a file."""
    return write_text_atomic(path, to_yaml_text(info))


def _read_matrix(doc: dict[str, Any], key: str, rows: int, cols: int | None = None) -> np.ndarray:
    m = doc.get(key)
    if not isinstance(m, dict) or "data" not in m:
        raise CameraYamlError(f"missing {key}" if m is None else f"{key}: not a matrix (rows, cols, data)")
    try:
        data = np.asarray(m["data"], float)
        c = cols if cols is not None else int(m.get("cols", data.size // rows))
    except (TypeError, ValueError):
        raise CameraYamlError(f"{key}: data and cols must be numbers, got {m.get('data')!r}") from None
    if data.ndim != 1 or not np.all(np.isfinite(data)):
        raise CameraYamlError(f"{key}: data must be a list of finite numbers, got {m.get('data')!r}")
    if data.size != rows * c:
        raise CameraYamlError(f"{key}: expected {rows}x{c} values, got {data.size}")
    return data.reshape(rows, c)


def read_camera_yaml(path: str | Path) -> CameraInfoData:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise CameraYamlError(f"{p}: {e}") from None
    if not isinstance(doc, dict):
        raise CameraYamlError(f"{p}: not a camera calibration YAML")
    try:
        return CameraInfoData(
            _size(doc, "image_width"), _size(doc, "image_height"), str(doc.get("camera_name") or ""),
            _read_matrix(doc, "camera_matrix", 3, 3), _read_matrix(doc, "distortion_coefficients", 1).ravel(),
            _text(doc, "distortion_model", "plumb_bob"), _read_matrix(doc, "rectification_matrix", 3, 3),
            _read_matrix(doc, "projection_matrix", 3, 4))
    except CameraYamlError as e:
        raise CameraYamlError(f"{p}: {e}") from None


def _size(doc: dict[str, Any], key: str) -> int:
    """A positive whole number of pixels; a missing, null or other value names the field."""
    if key not in doc:
        raise CameraYamlError(f"missing {key}")
    v = doc[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v) or v <= 0:
        raise CameraYamlError(f"{key} must be a positive whole number of pixels, got {v!r}")
    return int(v)


def _text(doc: dict[str, Any], key: str, default: str) -> str:
    """A string field (absent: ``default``); null or another type names the field."""
    v = doc.get(key, default)
    if not isinstance(v, str):
        raise CameraYamlError(f"{key} must be a string, got {v!r}")
    return v
