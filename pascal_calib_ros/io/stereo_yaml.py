"""The files of a calibrated stereo pair and of a camera rig.

- ``left.yaml`` / ``right.yaml``: camera_calibration_parsers YAML (:mod:`.camera_yaml`) as ROS
  ``camera_calibration``'s stereo calibrator writes them (its ``lryaml``; names
  ``NAME/left`` and ``NAME/right``): K and D of each camera, R its rectification rotation (R1,
  R2), P its rectified projection (P1, P2; the right camera's P[0, 3] = -fx' baseline). What
  ``camera_info_manager`` loads and ``stereo_image_proc`` rectifies with. Values are written in
  full precision (camera_calibration rounds K and P to 5 decimals, D to 6).
- ``stereo.yaml``: the pair's transform X_right = R X_left + T (metres; OpenCV's
  ``stereoCalibrate`` R, T), its sigma (deg about the right camera's axes, mm), the epipolar RMS
  of the rectified pair, the rectification (alpha, method, Q), and the right optical frame's pose
  in the left's with the ``static_transform_publisher`` line that publishes it.
- ``rig.yaml``: every camera's pose in the first camera's optical frame (p_first = R p_cam + t)
  with its sigma (about the first camera's axes), its camera YAML and its static transform line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError
from ..geometry import Camera, StereoRectification, Transform
from .atomic import write_text_atomic
from .calibration_json import CalibrationRecord
from .camera_yaml import CameraInfoData, camera_info_of, write_camera_yaml
from .tf_command import static_transform_command


class StereoYamlError(PascalCalibError):
    """The file is not a stereo.yaml or rig.yaml of this package."""


def _m(rows: int, cols: int, data: np.ndarray) -> dict[str, Any]:
    return {"rows": rows, "cols": cols, "data": [float(v) for v in np.asarray(data, float).ravel()]}


def _v(a: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(a, float).ravel()]


def _dump(path: Path, header: str, doc: dict[str, Any]) -> Path:
    """Write atomically (:mod:`.atomic`) with a comment header."""
    lines = "".join(f"# {h}\n" for h in header.splitlines())
    return write_text_atomic(path, lines + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=1000))


def pair_camera_infos(left: Camera, right: Camera, rect: StereoRectification, name: str = "narrow_stereo"
                      ) -> tuple[CameraInfoData, CameraInfoData]:
    """The two CameraInfo contents of a rectified pair: K, D of each camera, R = R1 / R2,
    P = P1 / P2, names ``name/left`` and ``name/right``."""
    return (camera_info_of(CalibrationRecord(left, f"{name}/left"), rect.R1, rect.P1),
            camera_info_of(CalibrationRecord(right, f"{name}/right"), rect.R2, rect.P2))


def write_pair_yamls(out_dir: str | Path, left: Camera, right: Camera, rect: StereoRectification,
                     name: str = "narrow_stereo", files: tuple[str, str] = ("left.yaml", "right.yaml")
                     ) -> tuple[Path, Path]:
    """``left.yaml`` and ``right.yaml`` (module docstring); camera names ``name/left``, ``name/right``."""
    out = Path(out_dir)
    infos = pair_camera_infos(left, right, rect, name)
    return write_camera_yaml(out / files[0], infos[0]), write_camera_yaml(out / files[1], infos[1])


@dataclass(frozen=True)
class StereoData:
    """What ``stereo.yaml`` holds (module docstring)."""

    left_name: str
    right_name: str
    left_frame: str
    right_frame: str
    width: int
    height: int
    rig: Transform  # X_right = R X_left + T
    sigma_rotation_deg: np.ndarray  # (3,) about the right camera's axes
    sigma_translation_mm: np.ndarray  # (3,)
    pose_sigma_rotation_deg: np.ndarray  # (3,) of the right frame's pose in the left's, about the left's axes
    pose_sigma_translation_mm: np.ndarray  # (3,)
    epipolar_rms_px: float
    rectification: StereoRectification

    def static_transform(self) -> str:
        return static_transform_command(self.rig.inverse(), self.left_frame, self.right_frame)


def write_stereo_yaml(path: str | Path, d: StereoData) -> Path:
    rect = d.rectification
    pose = d.rig.inverse()
    doc = {
        "left_camera": d.left_name, "right_camera": d.right_name,
        "image_width": int(d.width), "image_height": int(d.height),
        "R": _m(3, 3, d.rig.R), "T": _v(d.rig.translation),
        "baseline_m": float(np.linalg.norm(d.rig.translation)), "angle_deg": d.rig.angle_deg(),
        "sigma_rotation_deg": _v(d.sigma_rotation_deg), "sigma_translation_mm": _v(d.sigma_translation_mm),
        "epipolar_rms_px": float(d.epipolar_rms_px),
        "rectification": {"alpha": None if not np.isfinite(rect.alpha) else float(rect.alpha), "method": rect.method,
                          "half_field_deg": float(rect.half_field_deg), "baseline_m": rect.baseline,
                          "Q": _m(4, 4, rect.Q)},
        "right_in_left": {"parent_frame": d.left_frame, "child_frame": d.right_frame,
                          "translation": _v(pose.translation), "quaternion_xyzw": _v(pose.quat),
                          "sigma_rotation_deg": _v(d.pose_sigma_rotation_deg),
                          "sigma_translation_mm": _v(d.pose_sigma_translation_mm)},
        "static_transform_publisher": d.static_transform(),
    }
    header = ("Stereo pair: X_right = R X_left + T (metres), points of the left optical frame in the right's\n"
              "(OpenCV stereoCalibrate's R, T). sigma: per axis, small rotations about the right camera's axes (deg)\n"
              "and translations (mm). epipolar_rms_px: row differences of the same features in the rectified pair\n"
              "(left.yaml / right.yaml). right_in_left: the right optical frame's pose in the left's (tf parent left).")
    return _dump(Path(path), header, doc)


def _matrix(doc: dict[str, Any], key: str, rows: int, cols: int, where: Path) -> np.ndarray:
    m = doc.get(key)
    try:
        data = np.asarray(m["data"] if isinstance(m, dict) else m, float)
        return data.reshape(rows, cols)
    except (TypeError, ValueError, KeyError):
        raise StereoYamlError(f"{where}: {key} is not a {rows}x{cols} matrix") from None


def _load(path: str | Path) -> tuple[dict[str, Any], Path]:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise StereoYamlError(f"{p}: {e}") from None
    if not isinstance(doc, dict):
        raise StereoYamlError(f"{p}: not a YAML mapping")
    return doc, p


def read_stereo_yaml(path: str | Path) -> dict[str, Any]:
    """The pair's transform (``rig``: a Transform, X_right = R X_left + T), its sigmas, the
    epipolar RMS and the frames, from a ``stereo.yaml``."""
    doc, p = _load(path)
    try:
        R = _matrix(doc, "R", 3, 3, p)
        T = np.asarray(doc["T"], float).reshape(3)
        return {"rig": Transform.from_rt(R, T), "sigma_rotation_deg": np.asarray(doc["sigma_rotation_deg"], float),
                "sigma_translation_mm": np.asarray(doc["sigma_translation_mm"], float),
                "epipolar_rms_px": float(doc["epipolar_rms_px"]),
                "left_frame": doc["right_in_left"]["parent_frame"], "right_frame": doc["right_in_left"]["child_frame"],
                "left_camera": doc["left_camera"], "right_camera": doc["right_camera"]}
    except (KeyError, TypeError, ValueError) as e:
        raise StereoYamlError(f"{p}: missing or malformed {e}") from None


@dataclass(frozen=True)
class RigCameraData:
    """One camera of ``rig.yaml``: its pose in the first camera's frame and sigma (about the first
    camera's axes), its optical frame and camera YAML."""

    name: str
    frame: str
    yaml_file: str
    pose: Transform  # p_first = R p_cam + t
    sigma_rotation_deg: np.ndarray
    sigma_translation_mm: np.ndarray


def write_rig_yaml(path: str | Path, cameras: list[RigCameraData], shots_used: int) -> Path:
    ref = cameras[0]
    doc = {"reference_camera": ref.name, "reference_frame": ref.frame, "shots_used": int(shots_used),
           "cameras": [{"name": c.name, "frame": c.frame, "camera_yaml": c.yaml_file,
                        "translation": _v(c.pose.translation), "quaternion_xyzw": _v(c.pose.quat),
                        "sigma_rotation_deg": _v(c.sigma_rotation_deg),
                        "sigma_translation_mm": _v(c.sigma_translation_mm),
                        "static_transform_publisher": static_transform_command(c.pose, ref.frame, c.frame)}
                       for c in cameras]}
    header = (f"Camera rig: each camera's pose in {ref.name}'s optical frame (p_{ref.name} = R p_camera + t, metres;\n"
              "tf parent the reference frame), sigma per axis about the reference camera's axes (deg, mm).")
    return _dump(Path(path), header, doc)


def read_rig_yaml(path: str | Path) -> list[RigCameraData]:
    doc, p = _load(path)
    try:
        return [RigCameraData(c["name"], c["frame"], c["camera_yaml"],
                              Transform.from_quat(c["quaternion_xyzw"], c["translation"]),
                              np.asarray(c["sigma_rotation_deg"], float), np.asarray(c["sigma_translation_mm"], float))
                for c in doc["cameras"]]
    except (KeyError, TypeError, ValueError) as e:
        raise StereoYamlError(f"{p}: missing or malformed {e}") from None
