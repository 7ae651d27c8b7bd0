"""``pascal-calib verify``: fresh images against a calibration file (and a hand-eye result), the
verdict of :func:`~..analysis.verification.verify_calibration` and a JSON of every number.

The calibration's covariance comes from its ``calibration.json`` (given directly, or the
``CAM.calibration.json`` beside a ``CAM.yaml``); files of other tools have none (the verdict says
so). A hand-eye check needs the HAND_EYE.yaml under test and the robot pose of each image
(POSES.yaml, matched by file name).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analysis import DEFAULT_ALPHA, HandEyeReference, Verification, verify_calibration
from ..calibrate.handeye import HandEyeResult
from ..detect import Detection, DetectionParams
from ..errors import PascalCalibError
from ..geometry import MODELS, Transform
from ..io import CalibrationFile, CalibrationRecord, read_calibration_file, read_hand_eye_yaml, read_poses_yaml
from ..modes import HandEyeMode
from ..targets import Target, resolve_target
from .detection import detect_files


class VerifyInputError(PascalCalibError):
    """A verify input cannot be used (files, a hand-eye result without poses, ...)."""


@dataclass(frozen=True)
class VerifyRequest:
    target: str
    calibration: Path
    images: list[Path]
    hand_eye: Path | None = None
    poses: Path | None = None
    json_out: Path | None = None
    alpha: float = DEFAULT_ALPHA
    camera: str = ""  # the entry of a multi-camera calibration file
    gamma: float = 1.0
    max_blur: float = 4.0


@dataclass
class VerifyOutcome:
    verification: Verification
    lines: list[str] = field(default_factory=list)


def reference_of_file(cf: CalibrationFile) -> CalibrationRecord:
    """The calibration under test: the camera and, from its record, what was estimated and its
    covariance."""
    if cf.camera.model not in MODELS:
        raise VerifyInputError(f"{cf.path}: verify tests {', '.join(MODELS)} cameras; this one is an {cf.camera.model} "
                               "model (compare it with pascal-calib diff)")
    rec = cf.record
    if rec.covariance is None:  # what a later check needs is only the camera and its choice
        return CalibrationRecord(rec.camera, rec.camera_name, rec.distortion_choice)
    return rec


def hand_eye_reference(path: Path) -> HandEyeReference:
    doc, X = read_hand_eye_yaml(path)
    try:
        s_t = np.asarray(doc["translation_std_mm"], float).reshape(3)
        s_r = np.asarray(doc["rotation_std_deg"], float).reshape(3)
        mode = HandEyeMode(str(doc["mode"]))
    except (KeyError, TypeError, ValueError) as e:
        raise VerifyInputError(f"{path}: a hand-eye result needs mode (eye_in_hand or "
                               f"eye_to_hand), translation_std_mm and rotation_std_deg ({e!r})") from None
    if not (np.all(np.isfinite(s_t)) and np.all(np.isfinite(s_r))):
        raise VerifyInputError(f"{path}: the sigmas must be finite")
    share = [np.asarray(doc.get(k) or np.zeros(3), float).reshape(3)
             for k in ("translation_std_intrinsics_mm", "rotation_std_intrinsics_deg")]
    return HandEyeReference(mode, X, s_t, s_r, str(doc.get("parent_frame", "")), str(doc.get("child_frame", "")),
                            intrinsics_share_mm=share[0], intrinsics_share_deg=share[1])


def _robot_poses(req: VerifyRequest) -> list[Transform | None] | None:
    if req.hand_eye is None and req.poses is None:
        return None
    if req.hand_eye is None or req.poses is None:
        raise VerifyInputError("a hand-eye check needs both --hand-eye HAND_EYE.yaml and --poses POSES.yaml")
    _, _, poses = read_poses_yaml(req.poses)
    robot = [poses.get(p.name) for p in req.images]
    if not any(r is not None for r in robot):
        raise VerifyInputError(f"no image has a pose in {req.poses} (images are matched by file name)")
    return robot


def run_verify(req: VerifyRequest) -> VerifyOutcome:
    """Read, detect, verify, write the JSON (module docstring)."""
    if not req.images:
        raise VerifyInputError("no images given")
    target = resolve_target(req.target)
    cf = read_calibration_file(req.calibration, req.camera)
    ref = reference_of_file(cf)
    he = hand_eye_reference(req.hand_eye) if req.hand_eye is not None else None
    robot = _robot_poses(req)
    lines = [f"calibration: {req.calibration} ({cf.format}{', ' + ', '.join(cf.notes) if cf.notes else ''}), "
             f"{cf.camera.model}, {cf.camera.width}x{cf.camera.height}"
             + ("" if ref.covariance is not None else "; no stored covariance")]
    params = DetectionParams.for_lens(cf.camera.lens.wide, gamma=req.gamma, max_blur=req.max_blur)
    t0 = time.perf_counter()
    dets = detect_files(req.images, target, params)
    t1 = time.perf_counter()
    v = verify_calibration(dets, target, ref, robot, he, req.alpha)
    t2 = time.perf_counter()
    lines += v.text().splitlines()
    lines.append(f"time: detection {t1 - t0:.2f} s ({len(req.images)} images), verification {t2 - t1:.2f} s")
    if req.json_out is not None:
        doc = v.as_json()
        doc["calibration"] = str(req.calibration)
        doc["time_s"] = {"detection": t1 - t0, "verification": t2 - t1}
        req.json_out.parent.mkdir(parents=True, exist_ok=True)
        req.json_out.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
        lines.append(f"wrote {req.json_out}")
    return VerifyOutcome(v, lines)


def hand_eye_reference_of_result(he: HandEyeResult, parent_frame: str, camera_frame: str, arm_accuracy_mm: float,
                                 arm_accuracy_length: float) -> HandEyeReference:
    """A hand-eye result of this session as the one under test."""
    return HandEyeReference(he.mode, he.hand_eye, np.asarray(he.translation_std_mm, float),
                            np.asarray(he.rotation_std_deg, float), parent_frame, camera_frame,
                            arm_accuracy_mm=arm_accuracy_mm, arm_accuracy_length=arm_accuracy_length,
                            intrinsics_share_mm=np.asarray(he.intrinsics_share_mm, float),
                            intrinsics_share_deg=np.asarray(he.intrinsics_share_deg, float))


def verify_detections(dets: list[Detection], target: Target, reference: CalibrationRecord,
                 robot_poses: list[Transform | None] | None = None, hand_eye: HandEyeReference | None = None,
                 alpha: float = DEFAULT_ALPHA) -> tuple[Verification, str]:
    """The verification of collected views (the node's ``~/verify``) and its answer in one line: the
    verdict, what moved, the projection shift and, with a hand-eye check, how far X moved."""
    v = verify_calibration(dets, target, reference, robot_poses, hand_eye, alpha)
    lines = v.text().splitlines()
    keep = [lines[0]] + [ln for ln in lines[1:] if ln.startswith(("views:", "projection shift", "hand-eye:"))]
    return v, "; ".join(keep)
