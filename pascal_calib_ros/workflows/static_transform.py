"""The static transform a saved result stands for (what the ``publisher`` node broadcasts on /tf_static),
refused with the reason when the file does not hold one the calibration node would have published.

- ``hand_eye.yaml`` (:mod:`..io.hand_eye_yaml`): ``parent_frame`` -> ``child_frame`` (eye in hand: the
  tool -> the camera optical frame; eye to hand: the base -> the camera), the same transform as the
  node's ``~/hand_eye``; refused as the node refuses to publish (:func:`.hand_eye.hand_eye_doubts`): a
  transform or sigma that is not finite or missing, sigma above 5 mm / 0.5 deg on an axis.
- ``stereo.yaml`` (:mod:`..io.stereo_yaml`): ``left_frame`` -> ``right_frame``, the right optical frame's
  pose in the left's, as the stereo node's ``~/stereo_transform``; refused as the stereo node refuses
  (:func:`.stereo_session.stereo_doubts`): sigma above 0.5 deg / 5 mm, epipolar RMS above 1 px.
- ``rig.yaml`` (:mod:`..io.stereo_yaml`, ``pascal-calib rig``): the reference camera's optical frame ->
  each other camera's, one transform per camera; refused when any camera's pose is not finite or its
  sigma is above 0.5 deg / 5 mm (a rig is broadcast whole or not at all).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError
from ..geometry import Transform, TransformError
from ..io import PosesYamlError, StereoYamlError, read_hand_eye_yaml, read_rig_yaml, read_stereo_yaml
from .hand_eye import MAX_HAND_EYE_STD_DEG, MAX_HAND_EYE_STD_MM
from .stereo_session import MAX_EPIPOLAR_RMS_PX, MAX_SIGMA_DEG, MAX_SIGMA_MM


class ResultFileError(PascalCalibError):
    """A result file that cannot be read, or whose transform must not be broadcast (the message says why)."""


@dataclass(frozen=True)
class StaticTransform:
    """``pose``: the child frame's pose in the parent (child points into the parent frame)."""

    parent: str
    child: str
    pose: Transform
    kind: str  # "hand_eye eye_in_hand", "hand_eye eye_to_hand", "stereo"

    def describe(self) -> str:
        t, q = self.pose.translation, self.pose.quat
        return (f"{self.kind}: {self.parent} -> {self.child} t=[{t[0]:.6f}, {t[1]:.6f}, {t[2]:.6f}] m "
                f"q=[{q[0]:.7f}, {q[1]:.7f}, {q[2]:.7f}, {q[3]:.7f}]")


def _frame(doc: dict[str, Any], key: str, where: Path) -> str:
    v = doc.get(key)
    if not isinstance(v, str) or not v.strip():
        raise ResultFileError(f"{where}: {key} is missing or empty")
    return v


def _sigmas(v: Any, key: str, where: Path) -> np.ndarray:
    try:
        a = np.asarray(v, float).reshape(3)
    except (TypeError, ValueError):
        raise ResultFileError(f"{where}: {key} is missing or not 3 numbers: its transform is not stood "
                              "behind") from None
    if not np.all(np.isfinite(a)):
        raise ResultFileError(f"{where}: {key} is not finite: the uncertainty is unknown, the transform not stood "
                              "behind")
    return a


def _hand_eye(path: Path) -> StaticTransform:
    try:
        doc, X = read_hand_eye_yaml(path)
    except PosesYamlError as e:
        raise ResultFileError(str(e)) from None
    if not (np.all(np.isfinite(X.translation)) and np.all(np.isfinite(X.quat))):
        raise ResultFileError(f"{path}: the transform is not finite")
    t_std = _sigmas(doc.get("translation_std_mm"), "translation_std_mm", path)
    r_std = _sigmas(doc.get("rotation_std_deg"), "rotation_std_deg", path)
    doubts = []
    if t_std.max() > MAX_HAND_EYE_STD_MM:
        doubts.append(f"translation std up to {t_std.max():.2f} mm (> {MAX_HAND_EYE_STD_MM:g} mm)")
    if r_std.max() > MAX_HAND_EYE_STD_DEG:
        doubts.append(f"rotation std up to {r_std.max():.3f} deg (> {MAX_HAND_EYE_STD_DEG:g} deg)")
    if doubts:
        raise ResultFileError(f"{path}: the transform is not determined well enough: {'; '.join(doubts)}")
    mode = str(doc.get("mode", ""))
    return StaticTransform(_frame(doc, "parent_frame", path), _frame(doc, "child_frame", path), X,
                           f"hand_eye {mode}".strip())


def _stereo(path: Path) -> StaticTransform:
    try:
        d = read_stereo_yaml(path)
    except StereoYamlError as e:
        raise ResultFileError(str(e)) from None
    rig: Transform = d["rig"]
    if not (np.all(np.isfinite(rig.matrix))):
        raise ResultFileError(f"{path}: the rig transform is not finite")
    sr = _sigmas(d["sigma_rotation_deg"], "sigma_rotation_deg", path)
    st = _sigmas(d["sigma_translation_mm"], "sigma_translation_mm", path)
    if np.linalg.norm(sr) > MAX_SIGMA_DEG or np.linalg.norm(st) > MAX_SIGMA_MM:
        raise ResultFileError(f"{path}: the rig transform is not determined well enough: sigma "
                              f"{np.linalg.norm(sr):.3f} deg, {np.linalg.norm(st):.2f} mm (limits {MAX_SIGMA_DEG} deg, "
                              f"{MAX_SIGMA_MM} mm)")
    rms = float(d["epipolar_rms_px"])
    if not np.isfinite(rms) or rms > MAX_EPIPOLAR_RMS_PX:
        raise ResultFileError(f"{path}: epipolar RMS {rms:.3f} px (limit {MAX_EPIPOLAR_RMS_PX} px)")
    doc = {"left_frame": d["left_frame"], "right_frame": d["right_frame"]}
    return StaticTransform(_frame(doc, "left_frame", path), _frame(doc, "right_frame", path), rig.inverse(), "stereo")


def _rig(path: Path) -> list[StaticTransform]:
    try:
        cams = read_rig_yaml(path)
    except (StereoYamlError, TransformError) as e:
        raise ResultFileError(str(e)) from None
    if len(cams) < 2:
        raise ResultFileError(f"{path}: a rig of {len(cams)} camera(s): nothing to broadcast")
    out = []
    for c in cams[1:]:
        if not np.all(np.isfinite(c.pose.matrix)):
            raise ResultFileError(f"{path}: camera {c.name}'s pose is not finite")
        sr, st = np.asarray(c.sigma_rotation_deg, float), np.asarray(c.sigma_translation_mm, float)
        if sr.shape != (3,) or st.shape != (3,) or not (np.all(np.isfinite(sr)) and np.all(np.isfinite(st))):
            raise ResultFileError(f"{path}: camera {c.name}'s sigmas are missing or not finite")
        if np.any(sr > MAX_SIGMA_DEG) or np.any(st > MAX_SIGMA_MM):
            raise ResultFileError(f"{path}: camera {c.name}'s pose is not determined well enough: sigma "
                                  f"{np.round(sr, 4).tolist()} deg, {np.round(st, 3).tolist()} mm (limits "
                                  f"{MAX_SIGMA_DEG:g} deg, {MAX_SIGMA_MM:g} mm)")
        out.append(StaticTransform(cams[0].frame, c.frame, c.pose, "rig"))
    return out


def read_result_transforms(path: str | Path) -> list[StaticTransform]:
    """The static transforms of a saved ``hand_eye.yaml``, ``stereo.yaml`` (one) or ``rig.yaml`` (one per
    camera but the reference; the kind read from its keys), or :class:`ResultFileError` with the reason
    they cannot be broadcast."""
    p = Path(path).expanduser()
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ResultFileError(f"{p}: cannot read ({e})") from None
    if isinstance(doc, dict) and "cameras" in doc and "reference_frame" in doc:
        return _rig(p)
    return [read_result_transform(p)]


def read_result_transform(path: str | Path) -> StaticTransform:
    """The static transform of a saved ``hand_eye.yaml`` or ``stereo.yaml`` (the kind read from its keys),
    or :class:`ResultFileError` with the reason it cannot be broadcast."""
    p = Path(path).expanduser()
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ResultFileError(f"{p}: cannot read ({e})") from None
    if isinstance(doc, dict) and "right_in_left" in doc:
        return _stereo(p)
    if isinstance(doc, dict) and "parent_frame" in doc and "translation" in doc:
        return _hand_eye(p)
    raise ResultFileError(f"{p}: neither a hand-eye result (hand_eye.yaml: parent_frame, translation, rotation, ...), "
                          "a stereo result (stereo.yaml: R, T, right_in_left, ...) nor a rig (rig.yaml: "
                          "reference_frame, cameras)")
