"""Robot poses in (POSES.yaml) and the hand-eye result out (HAND_EYE.yaml).

POSES.yaml, one entry per image, matched by file name::

    frame_id: base_link          # robot base
    child_frame_id: tool0        # tool / flange
    poses:
      - image: view_00.png
        translation: [0.412, -0.105, 0.530]     # metres, tool origin in the base frame
        rotation: [0.0, 0.7071068, 0.0, 0.7071068]   # unit quaternion x, y, z, w (ROS order)

HAND_EYE.yaml::

    mode: eye_in_hand                       # or eye_to_hand
    parent_frame: tool0                     # eye_in_hand: the tool; eye_to_hand: the base
    child_frame: camera_optical_frame       # x right, y down, z forward (ROS optical frame)
    translation: [x, y, z]                  # metres: camera origin in the parent frame
    rotation: [qx, qy, qz, qw]
    translation_std_mm: [sx, sy, sz]       # along the parent frame's axes
    rotation_std_deg: [rx, ry, rz]         # small rotations about the parent frame's axes
    translation_std_intrinsics_mm: [..]    # of those sigmas, the held intrinsics' share (the same error moves
    rotation_std_intrinsics_deg: [..]      # every X estimated with these intrinsics: verify leaves it out)
    target_frame: base_link                 # where the target was estimated (eye_to_hand: the tool)
    target_translation: [x, y, z]           # target origin (the target YAML's frame) in target_frame
    target_rotation: [qx, qy, qz, qw]
    views_used: 18
    rms_px: 0.05

Quaternions within 1e-3 of unit norm are normalised, others refused
(:data:`~..geometry.transform.QUAT_TOLERANCE`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError
from ..geometry import Transform, TransformError
from ..modes import HandEyeMode
from .atomic import write_text_atomic


class PosesYamlError(PascalCalibError):
    """The robot pose file cannot be used; the message says where and why."""


def read_poses_yaml(path: str | Path) -> tuple[str, str, dict[str, Transform]]:
    """(frame_id, child_frame_id, {image file name: T_frame_child})."""
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as e:
        raise PosesYamlError(f"{p}: cannot read ({e.strerror or e})") from None
    except yaml.YAMLError as e:
        raise PosesYamlError(f"{p}: not valid YAML ({str(e).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise PosesYamlError(f"{p}: expected a mapping with frame_id, child_frame_id and poses")
    frames = []
    for key in ("frame_id", "child_frame_id"):
        v = doc.get(key)
        if not isinstance(v, str) or not v.strip():
            raise PosesYamlError(f"{p}: '{key}' missing or not a frame name")
        frames.append(v.strip())
    entries = doc.get("poses")
    if not isinstance(entries, list) or not entries:
        raise PosesYamlError(f"{p}: 'poses' must be a non-empty list of {{image, translation, rotation}}")
    out: dict[str, Transform] = {}
    for k, entry in enumerate(entries):
        where = f"{p}: poses[{k}]"
        if not isinstance(entry, dict):
            raise PosesYamlError(f"{where}: expected a mapping with image, translation, rotation")
        name = entry.get("image")
        if not isinstance(name, str) or not name.strip():
            raise PosesYamlError(f"{where}: 'image' missing")
        name = Path(name.strip()).name
        where = f"{where} ({name})"
        if name in out:
            raise PosesYamlError(f"{where}: a second pose for the same image")
        for key in ("translation", "rotation"):
            if key not in entry:
                raise PosesYamlError(f"{where}: '{key}' missing")
        try:
            out[name] = Transform.from_quat(_numbers(entry["rotation"], 4, where + " rotation"),
                                            _numbers(entry["translation"], 3, where + " translation"))
        except TransformError as err:
            raise PosesYamlError(f"{where}: {err}") from None
    return frames[0], frames[1], out


def _numbers(v: Any, n: int, where: str) -> list[float]:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise PosesYamlError(f"{where}: expected a list of {n} numbers, got {v!r}")
    try:
        out = [float(x) for x in v]
    except (TypeError, ValueError):
        raise PosesYamlError(f"{where}: expected numbers, got {v!r}") from None
    if not all(np.isfinite(out)):
        raise PosesYamlError(f"{where}: numbers must be finite, got {v!r}")
    return out


def write_poses_yaml(path: str | Path, frame_id: str, child_frame_id: str, poses: dict[str, Transform]) -> Path:
    """Write a POSES.yaml (simulated sessions, tests)."""
    doc = {"frame_id": frame_id, "child_frame_id": child_frame_id,
           "poses": [{"image": name, "translation": _floats(T.translation), "rotation": _floats(T.quat)}
                     for name, T in poses.items()]}
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return p


def _floats(v: np.ndarray | tuple[float, ...]) -> list[float]:
    return [float(x) for x in np.asarray(v, float).ravel()]


@dataclass(frozen=True)
class HandEyeRecord:
    """What HAND_EYE.yaml holds (module docstring): the camera's pose ``X`` in ``parent_frame``
    (camera-frame points into the parent frame) with its standard deviations (mm, deg per parent
    axis), the target's pose ``target`` in ``target_frame``, the views used and the RMS (px)."""

    mode: HandEyeMode
    parent_frame: str
    child_frame: str
    X: Transform
    translation_std_mm: tuple[float, float, float]
    rotation_std_deg: tuple[float, float, float]
    target_frame: str
    target: Transform
    views_used: int
    rms_px: float
    # of the sigmas, the held intrinsics' share: the same intrinsics error moves every X estimated with these
    # intrinsics alike (pascal-calib verify leaves it out of the comparison)
    translation_std_intrinsics_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_std_intrinsics_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def document(self) -> dict[str, Any]:
        """The YAML mapping."""
        return {
            "mode": self.mode,
            "parent_frame": self.parent_frame,
            "child_frame": self.child_frame,
            "translation": _floats(self.X.translation),
            "rotation": _floats(self.X.quat),
            "translation_std_mm": _floats(self.translation_std_mm),
            "rotation_std_deg": _floats(self.rotation_std_deg),
            "translation_std_intrinsics_mm": _floats(self.translation_std_intrinsics_mm),
            "rotation_std_intrinsics_deg": _floats(self.rotation_std_intrinsics_deg),
            "target_frame": self.target_frame,
            "target_translation": _floats(self.target.translation),
            "target_rotation": _floats(self.target.quat),
            "views_used": int(self.views_used),
            "rms_px": float(self.rms_px),
        }


def write_hand_eye_yaml(path: str | Path, record: HandEyeRecord) -> Path:
    """Write HAND_EYE.yaml (module docstring) atomically (:mod:`.atomic`); returns the path."""
    return write_text_atomic(path, yaml.safe_dump(record.document(), sort_keys=False, default_flow_style=None))


def read_hand_eye_yaml(path: str | Path) -> tuple[dict[str, Any], Transform]:
    """The document and the hand-eye transform of a HAND_EYE.yaml."""
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise PosesYamlError(f"{p}: cannot read ({e})") from None
    if not isinstance(doc, dict) or "translation" not in doc or "rotation" not in doc:
        raise PosesYamlError(f"{p}: not a hand-eye YAML")
    try:
        X = Transform.from_quat(_numbers(doc["rotation"], 4, "rotation"),
                                _numbers(doc["translation"], 3, "translation"))
    except TransformError as e:
        raise PosesYamlError(f"{p}: {e}") from None
    return doc, X
