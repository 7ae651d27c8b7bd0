"""Read and write the ROS ``camera_calibration_parsers`` YAML (the format of camera_info_manager).

Layout (monocular): image_width, image_height, camera_name, camera_matrix, distortion_model,
distortion_coefficients, rectification_matrix (identity), projection_matrix (P = [K | 0]).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError


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
    """Write atomically (temporary file then rename), so a reader never sees half a file."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(to_yaml_text(info))
    tmp.replace(p)
    return p


def _read_matrix(doc: dict[str, Any], key: str, rows: int, cols: int | None = None) -> np.ndarray:
    m = doc.get(key)
    if not isinstance(m, dict) or "data" not in m:
        raise CameraYamlError(f"missing {key}")
    data = np.asarray(m["data"], float)
    c = cols if cols is not None else int(m.get("cols", data.size // rows))
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
            int(doc["image_width"]), int(doc["image_height"]), str(doc.get("camera_name", "")),
            _read_matrix(doc, "camera_matrix", 3, 3), _read_matrix(doc, "distortion_coefficients", 1).ravel(),
            str(doc.get("distortion_model", "plumb_bob")), _read_matrix(doc, "rectification_matrix", 3, 3),
            _read_matrix(doc, "projection_matrix", 3, 4))
    except KeyError as e:
        raise CameraYamlError(f"{p}: missing {e}") from None
