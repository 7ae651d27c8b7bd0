"""``pascal-calib study verify``: does ``verify`` say *holds* when nothing changed and *changed*
when something did? The issue's goals, measured on renders.

Camera (intrinsics): ``sessions`` verification sessions of ``views`` views each, against a
calibration of ``cal_views`` views; a new calibration session every ``per_calibration`` sessions
(each with its own poses and noise). Every verification session is rendered four times from the
same poses: the camera unchanged, its focal length times 1.002 (fx and fy; the principal point
kept), its principal point moved by 1.5 px in a random direction, and (from the same seed) nothing
changed but new noise. Goal: *holds* in at least 19 of 20 unchanged sessions, *changed* in at
least 19 of 20 after each change, with the moved parameters named (fx/fy; cx/cy).

Hand-eye: an arm session of ``cal_views`` poses (eye in hand, :mod:`~..sim.arm`: arm noise 0.1 mm /
0.01 deg per axis and pose and one arm's systematic field of 0.25 mm) calibrated with
:func:`~..calibrate.handeye.calibrate_hand_eye`; fresh arm sessions of ``views`` poses with the
camera unchanged and turned by 0.1 deg on its mount (X' = X R, a random axis), verified with the
robot poses. Goal: *holds* / *changed* (naming X) in 19 of 20.

Time: one verification (the test on detections, as the node's ``~/verify`` runs it; and the
detection of the images before it) of 10 views at 1280x800, median of 3. Goal: under 2 s.

Writes ``verify_study.json`` (every session's verdict, what was named, the projection shift, the
time) and ``verify_study.md`` (the table) to ``out``.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import CHANGED, HandEyeReference, Verification, verify_calibration
from ..calibrate import CalibrationOptions, calibrate
from ..calibrate.handeye import calibrate_hand_eye
from ..detect import Detection, DetectionParams, detect_target
from ..geometry import Camera, Transform
from ..io import CalibrationRecord
from ..sim import DEFAULT_HAND_EYE, ArmSpec, SessionSpec, arm_poses, render_arm_images, render_view, session_views
from ..targets import Target, resolve_target
from ..workflows import intrinsic_covariance


@dataclass(frozen=True)
class StudySpec:
    sessions: int = 20
    views: int = 10
    cal_views: int = 20
    per_calibration: int = 4
    width: int = 640
    height: int = 480
    target: str = "ring_grid_a4"
    k1: float = -0.2
    gamma: float = 2.2  # the renders' display gamma, given to the detector as a user of such a camera would
    seed: int = 1
    camera: bool = True  # run the intrinsic scenarios
    hand_eye: bool = True  # ... the hand-eye scenarios
    timing: bool = True  # ... the timing at 1280x800


def _changed(cam: Camera, focal: float = 1.0, dpp: tuple[float, float] = (0.0, 0.0)) -> Camera:
    K = cam.K.copy()
    K[0, 0] *= focal
    K[1, 1] *= focal
    K[0, 2] += dpp[0]
    K[1, 2] += dpp[1]
    return Camera(K, cam.D.copy(), cam.width, cam.height, cam.model)


def _detect(target: Target, cam: Camera, spec: SessionSpec, params: DetectionParams) -> list[Detection]:
    return [detect_target(render_view(target, cam, pose, sens).image, target, params, name=name)
            for name, pose, sens in session_views(target, spec)]


def _reference(target: Target, spec: SessionSpec, params: DetectionParams) -> CalibrationRecord:
    res = calibrate(_detect(target, spec.camera(), spec, params), target, CalibrationOptions())
    names, cov = intrinsic_covariance(res)
    return CalibrationRecord(res.camera(), distortion_choice=res.distortion_model, parameters=names, covariance=cov)


def _row(kind: str, session: int, v: Verification, seconds: float, expect: str) -> dict[str, Any]:
    shift = v.intrinsics.shift
    return {"kind": kind, "session": session, "verdict": v.verdict, "expected": expect, "moved": v.moved,
            "projection_shift_rms_px": shift.rms if shift else None,
            "expected_shift_rms_px": v.intrinsics.expected_shift_rms_px,
            "min_p": min([g.p_value for g in v.intrinsics.groups]
                         + ([v.hand_eye.p_value] if v.hand_eye is not None else [])),
            "hand_eye_rotation_deg": v.hand_eye.rotation_deg if v.hand_eye is not None else None,
            "hand_eye_translation_mm": v.hand_eye.translation_mm if v.hand_eye is not None else None,
            "seconds": seconds, "views_used": len(v.fresh.used)}


def camera_sessions(s: StudySpec, log: Callable[[str], None]) -> list[dict[str, Any]]:
    """The intrinsic scenarios (module docstring)."""
    target = resolve_target(s.target)
    params = DetectionParams(gamma=s.gamma)
    rng = np.random.default_rng(s.seed)
    rows: list[dict[str, Any]] = []
    ref: CalibrationRecord | None = None
    for k in range(s.sessions):
        if k % s.per_calibration == 0:
            cal = SessionSpec(width=s.width, height=s.height, k1=s.k1, views=s.cal_views, seed=10_000 * s.seed + k)
            ref = _reference(target, cal, params)
        assert ref is not None
        fresh = SessionSpec(width=s.width, height=s.height, k1=s.k1, views=s.views, seed=20_000 * s.seed + k)
        truth = fresh.camera()
        ang = rng.uniform(0, 2 * np.pi)
        cases = [("unchanged", truth, "holds"), ("focal x 1.002", _changed(truth, 1.002), CHANGED),
                 ("principal point 1.5 px", _changed(truth, dpp=(1.5 * np.cos(ang), 1.5 * np.sin(ang))), CHANGED)]
        for kind, cam, expect in cases:
            dets = _detect(target, cam, fresh, params)
            t0 = time.perf_counter()
            v = verify_calibration(dets, target, ref)
            rows.append(_row(kind, k, v, time.perf_counter() - t0, expect))
            log(f"{kind:<24} session {k:2d}: {v.verdict:<8} moved {v.moved}  min p {rows[-1]['min_p']:.1e}")
    return rows


def _arm_reference(target: Target, spec: ArmSpec, params: DetectionParams
                   ) -> tuple[CalibrationRecord, HandEyeReference]:
    session = arm_poses(spec, target)
    imgs = render_arm_images(session, target)
    dets = [detect_target(im, target, params, name=n) for im, n in zip(imgs, session.names, strict=True)]
    res = calibrate_hand_eye(dets, list(session.robot_poses), target, spec.mode, CalibrationOptions())
    names, cov = intrinsic_covariance(res.calibration)
    ref = CalibrationRecord(res.calibration.camera(), distortion_choice=res.calibration.distortion_model,
                            parameters=names, covariance=cov)
    he = HandEyeReference(spec.mode, res.hand_eye, res.translation_std_mm, res.rotation_std_deg,
                          intrinsics_share_mm=res.intrinsics_share_mm, intrinsics_share_deg=res.intrinsics_share_deg)
    return ref, he


def hand_eye_sessions(s: StudySpec, log: Callable[[str], None]) -> list[dict[str, Any]]:
    """The hand-eye scenarios (module docstring); eye in hand."""
    target = resolve_target(s.target)
    params = DetectionParams(gamma=s.gamma)
    rng = np.random.default_rng(s.seed + 7)
    rows: list[dict[str, Any]] = []
    refs: tuple[CalibrationRecord, HandEyeReference] | None = None
    base = ArmSpec(width=s.width, height=s.height, k1=s.k1, field_seed=s.seed)
    X_true = DEFAULT_HAND_EYE[base.mode]
    for k in range(s.sessions):
        if k % s.per_calibration == 0:
            refs = _arm_reference(target, replace(base, views=s.cal_views, seed=30_000 * s.seed + k), params)
        assert refs is not None
        axis = rng.normal(size=3)
        turned = X_true @ Transform.from_rotvec(np.radians(0.1) * axis / np.linalg.norm(axis))
        for kind, X, expect in (("hand-eye unchanged", X_true, "holds"), ("camera turned 0.1 deg", turned, CHANGED)):
            sess = arm_poses(replace(base, views=s.views, seed=40_000 * s.seed + k), target, hand_eye=X)
            imgs = render_arm_images(sess, target)
            dets = [detect_target(im, target, params, name=n) for im, n in zip(imgs, sess.names, strict=True)]
            t0 = time.perf_counter()
            v = verify_calibration(dets, target, refs[0], list(sess.robot_poses), refs[1])
            rows.append(_row(kind, k, v, time.perf_counter() - t0, expect))
            log(f"{kind:<24} session {k:2d}: {v.verdict:<8} moved {v.moved}  X {v.hand_eye.rotation_deg:.4f} deg"
                if v.hand_eye else "")
    return rows


def timing(s: StudySpec, log: Callable[[str], None], repeats: int = 3) -> dict[str, Any]:
    """Median time of one verification of ``s.views`` views at 1280x800 (and of their detection)."""
    target = resolve_target(s.target)
    params = DetectionParams(gamma=s.gamma)
    cal = SessionSpec(width=1280, height=800, k1=s.k1, views=s.cal_views, seed=50_000 + s.seed)
    ref = _reference(target, cal, params)
    fresh = SessionSpec(width=1280, height=800, k1=s.k1, views=s.views, seed=60_000 + s.seed)
    images = [render_view(target, fresh.camera(), p, sens).image for _, p, sens in session_views(target, fresh)]
    t_det, t_ver, cpu_ver = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        dets = [detect_target(im, target, params) for im in images]
        t1, c1 = time.perf_counter(), time.process_time()
        verify_calibration(dets, target, ref)
        t_det.append(t1 - t0)
        t_ver.append(time.perf_counter() - t1)
        cpu_ver.append(time.process_time() - c1)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    out = {"detection_s": float(np.median(t_det)), "verification_s": float(np.median(t_ver)),
           "verification_cpu_s": float(np.median(cpu_ver)), "load_average": load, "cpus": os.cpu_count(),
           "views": s.views, "size": "1280x800"}
    log(f"one verification of {s.views} views at 1280x800: {out['verification_s']:.2f} s "
        f"({out['verification_cpu_s']:.2f} s of CPU; load average {load:.1f} on {os.cpu_count()} CPUs; detection "
        f"before it {out['detection_s']:.2f} s)")
    return out


def summary_table(rows: list[dict[str, Any]], timed: dict[str, Any] | None) -> str:
    """The Markdown table of the study's figures."""
    lines = ["| scenario | sessions | verdict as expected | named | median projection shift (px) | median time (s) |",
             "|---|---|---|---|---|---|"]
    for kind in dict.fromkeys(r["kind"] for r in rows):
        rs = [r for r in rows if r["kind"] == kind]
        ok = sum(r["verdict"] == r["expected"] for r in rs)
        named: dict[str, int] = {}
        for r in rs:
            for m in r["moved"]:
                named[m] = named.get(m, 0) + 1
        shift = np.median([r["projection_shift_rms_px"] for r in rs if r["projection_shift_rms_px"] is not None])
        names = ", ".join(f"{n} {c}" for n, c in sorted(named.items(), key=lambda x: -x[1])) or "-"
        lines.append(f"| {kind} (expect {rs[0]['expected']}) | {len(rs)} | {ok} of {len(rs)} | {names} | "
                     f"{shift:.3f} | {np.median([r['seconds'] for r in rs]):.2f} |")
    if timed:
        lines.append(f"\nOne verification of {timed['views']} views at {timed['size']}: "
                     f"{timed['verification_s']:.2f} s, {timed['verification_cpu_s']:.2f} s of CPU (median of 3; "
                     f"load average {timed['load_average']:.1f} on {timed['cpus']} CPUs); the detection of its "
                     f"images before it: {timed['detection_s']:.2f} s.")
    return "\n".join(lines)


def verify_study(out: Path, spec: StudySpec = StudySpec(), log: Callable[[str], None] = print) -> dict[str, Any]:
    """Run the study (module docstring); returns and writes its numbers."""
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows = camera_sessions(spec, log) if spec.camera else []
    if spec.hand_eye:
        rows += hand_eye_sessions(spec, log)
    timed = timing(spec, log) if spec.timing else None
    doc = {"spec": spec.__dict__, "rows": rows, "timing": timed, "seconds": time.perf_counter() - t0}
    (out / "verify_study.json").write_text(json.dumps(doc, indent=1, default=float))
    table = summary_table(rows, timed)
    (out / "verify_study.md").write_text(table + "\n")
    log(table)
    return doc
