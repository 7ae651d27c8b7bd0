"""Stereo accuracy study (``pascal-calib study stereo``): a rendered stereo head against its
ground truth, beside OpenCV's ``stereoCalibrate`` on checkerboard renders of the same shots, and
whether the reported sigmas cover the errors.

The head (:func:`~..sim.rig.stereo_pair`): 800x600, f = 800 px, k1 = -0.2 (and a plausible k2,
p1, p2), baseline 12 cm, 2 degrees between the cameras, the right camera's intrinsics and
distortion a little different from the left's; ``views`` shots that both cameras see whole plus
2 that one camera sees whole; display gamma 2.2, noise 1.5 grey levels, blur 1 px.

1. **Accuracy** over ``sessions`` sessions (new shots and noise each): the error of the rig
   rotation (deg) and translation (mm), and of each camera's f (%) and c (px), for

   - ours: ``ring_grid_a4``, :func:`~..calibrate.rig.calibrate_rig` (detection with gamma 2.2);
   - OpenCV on ``checkerboard_a4`` rendered from the same shots with the same cameras (shots where
     both cameras see the whole board), corners by ``findChessboardCornersSB`` refined by
     ``cornerSubPix`` with a window per corner (as the ``lenses`` study), the 180 degree order
     ambiguity resolved between the two cameras by the direction of the corner grid:
     ``calibrateCamera`` per camera, then ``stereoCalibrate`` with ``CALIB_FIX_INTRINSIC`` (what
     ROS ``camera_calibration`` does) and with ``CALIB_USE_INTRINSIC_GUESS`` (both cameras refined
     with the rig).
2. **Trust**: ``draws`` calibrations of one session's shots with new sensor noise, and ``draws``
   new sessions; per quantity (rotation about x, y, z of the right camera; translation x, y, z;
   each camera's fx, fy, cx, cy) the spread of the estimates over the mean sigma (1 when sigma
   describes the noise), the worst |error| / sigma, and over new sessions the spread and worst of
   the z-scores error / sigma (as ``sim/trust_study.py`` does for one camera).
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ..calibrate import CalibrationError, calibrate_rig
from ..detect import DetectionParams, detect_target
from ..geometry import Transform
from ..sim import Pose, RigSession, RigSpec, features_in_image, render_rig, render_view, stereo_pair
from ..targets import resolve_target
from .study import opencv_board_corners, write_rows

GOALS = {"rot_err_deg": 0.005, "trans_err_mm": 0.1, "f_err_pct": 0.02, "c_err_px": 0.3}
QUANTITIES = ("rot_x", "rot_y", "rot_z", "t_x", "t_y", "t_z",
              *(f"{c}_{p}" for c in ("left", "right") for p in ("fx", "fy", "cx", "cy")))


def study_spec(views: int, seed: int) -> RigSpec:
    return RigSpec(stereo_pair(800, 600, k1=-0.2), shots=views, single_shots=2, seed=seed)


def _errors(rot: np.ndarray, trans: np.ndarray, Ks: list[np.ndarray], session: RigSession) -> dict[str, Any]:
    """Errors of an estimate (rotation matrix, T in metres, each camera's K) against the truth."""
    Et = session.extrinsic(1)
    dr = np.degrees((Rotation.from_matrix(rot) * Et.rotation.inv()).as_rotvec())
    dt = 1000 * (np.asarray(trans, float).ravel() - Et.translation)
    row: dict[str, Any] = {"rot_err_deg": float(np.linalg.norm(dr)), "trans_err_mm": float(np.linalg.norm(dt))}
    f_err, c_err = [], []
    for c, K in enumerate(Ks):
        Kt = session.spec.cameras[c].camera.K
        f_err += [100 * (K[0, 0] / Kt[0, 0] - 1), 100 * (K[1, 1] / Kt[1, 1] - 1)]
        c_err += [K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]]
    row["f_err_pct"] = float(np.max(np.abs(f_err)))
    row["c_err_px"] = float(np.max(np.abs(c_err)))
    row["signed"] = {"rot": dr.tolist(), "t": dt.tolist(), "f": f_err, "c": c_err}
    return row


def _ours(session: RigSession, noise_seed: int | None = None) -> dict[str, Any]:
    """Our calibration of the session's ring grid renders (with a new noise seed if given)."""
    grid = resolve_target("ring_grid_a4")
    if noise_seed is not None:
        session = _rerendered(session, noise_seed)
    params = DetectionParams(gamma=session.spec.gamma)
    dets = [[detect_target(im, grid, params, name=n) for im, n in zip(ims, session.names, strict=True)]
            for ims in session.images]
    try:
        res = calibrate_rig(dets, grid, ["left", "right"])
    except CalibrationError as e:
        return {"error": str(e)}
    E = res.extrinsics[1]
    row = _errors(E.R, E.translation, [r.K for r in res.cameras], session)
    sr, st = res.extrinsic_sigma[1]
    sig = [*sr, *st]
    for r in res.cameras:
        sig += [r.std.get(k, np.nan) for k in ("fx", "fy", "cx", "cy")]
    est = [*np.degrees(E.rotvec), *1000 * E.translation]
    for r in res.cameras:
        est += [r.K[0, 0], r.K[1, 1], r.K[0, 2], r.K[1, 2]]
    sg = row["signed"]
    err = [*sg["rot"], *sg["t"], *[(r.K[i, j] - rc.camera.K[i, j]) for r, rc in zip(res.cameras, session.spec.cameras,
                                                                                   strict=True)
                                   for i, j in ((0, 0), (1, 1), (0, 2), (1, 2))]]
    row.update(method="ours, ring_grid_a4", shots=int(np.sum(res.used.all(0))), rms=res.rms,
               sigma=dict(zip(QUANTITIES, map(float, sig), strict=True)),
               est=dict(zip(QUANTITIES, map(float, est), strict=True)),
               err=dict(zip(QUANTITIES, map(float, err), strict=True)),
               rot_sigma_deg=float(np.linalg.norm(sr)), trans_sigma_mm=float(np.linalg.norm(st)))
    return row


def _rerendered(session: RigSession, noise_seed: int) -> RigSession:
    """The session's shots rendered again with new sensor noise."""
    spec = replace(session.spec, seed=noise_seed)  # the seed only picks the noise here: the shots are kept
    grid = resolve_target(session.target)
    images = [[render_view(grid, rc.camera, _pose(session.view_pose(c, s)), spec.sensor(c, s)).image
               for s in range(len(session.names))] for c, rc in enumerate(spec.cameras)]
    return RigSession(session.spec, session.target, session.shot_poses, session.names, session.seen, images)


def _pose(T: Transform) -> Pose:
    return Pose(T.R, T.translation.copy())


def _board_pairs(session: RigSession) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Checkerboard corners of both cameras for the shots where both find the whole board, the
    right camera's order turned to agree with the left's; and the board's object points."""
    board_t = resolve_target("checkerboard_a4")
    board = board_t.checkerboards[0]
    left, right = [], []
    for s in range(len(session.names)):
        found = []
        for c, rc in enumerate(session.spec.cameras):
            pose = _pose(session.view_pose(c, s))
            if not features_in_image(board_t, rc.camera, pose, margin=3.0):
                break
            img = render_view(board_t, rc.camera, pose, session.spec.sensor(c, s)).image
            corners = opencv_board_corners(img, board.inner_corners, subpix=True)
            if corners is None:
                break
            found.append(corners)
        if len(found) == 2:
            a, b = found
            if np.dot(a[-1] - a[0], b[-1] - b[0]) < 0:  # the grid found from its other end (180 degrees)
                b = b[::-1].copy()
            left.append(a)
            right.append(b)
    obj = board.corner_points()
    return left, right, np.c_[obj, np.zeros(len(obj))]


def _opencv(session: RigSession) -> list[dict[str, Any]]:
    """OpenCV's calibrateCamera per camera, then stereoCalibrate (FIX_INTRINSIC; USE_INTRINSIC_GUESS)."""
    left, right, obj = _board_pairs(session)
    if len(left) < 3:
        return [{"method": "OpenCV stereoCalibrate", "error": f"board found by both cameras in {len(left)} shots"}]
    size = (session.spec.cameras[0].camera.width, session.spec.cameras[0].camera.height)
    o = [obj.astype(np.float32)] * len(left)
    ls, rs = [p.astype(np.float32) for p in left], [p.astype(np.float32) for p in right]
    _, K1, D1, _, _ = cv2.calibrateCamera(o, ls, size, None, None)
    _, K2, D2, _, _ = cv2.calibrateCamera(o, rs, size, None, None)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rows = []
    for flag, name in ((cv2.CALIB_FIX_INTRINSIC, "FIX_INTRINSIC (camera_calibration)"),
                       (cv2.CALIB_USE_INTRINSIC_GUESS, "USE_INTRINSIC_GUESS (joint)")):
        rms, k1, _, k2, _, R, T, _, _ = cv2.stereoCalibrate(o, ls, rs, K1.copy(), D1.copy(), K2.copy(), D2.copy(),
                                                            size, flags=flag, criteria=crit)
        row = _errors(np.asarray(R), np.asarray(T), [np.asarray(k1), np.asarray(k2)], session)
        row.update(method=f"OpenCV stereoCalibrate {name}, checkerboard_a4", shots=len(left), rms=float(rms))
        rows.append(row)
    return rows


def _accuracy_job(args: tuple[int, int]) -> list[dict[str, Any]]:
    views, seed = args
    session = render_rig(resolve_target("ring_grid_a4"), study_spec(views, seed))
    rows = [_ours(session), *_opencv(session)]
    for r in rows:
        r["session"] = seed
    return rows


def _trust_job(args: tuple[int, int, int, str]) -> dict[str, Any]:
    views, seed, draw, mode = args
    if mode == "session":
        return _ours(render_rig(resolve_target("ring_grid_a4"), study_spec(views, seed + 100 * (draw + 1))))
    session = render_rig(resolve_target("ring_grid_a4"), study_spec(views, seed))
    return _ours(session, noise_seed=10_000 * (draw + 1) + seed)


def accuracy_table(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per method: median and worst of each error over the sessions, and the goals."""
    out = []
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for m in methods:
        ok = [r for r in rows if r["method"] == m and "error" not in r]
        t: dict[str, Any] = {"method": m, "sessions": f"{len(ok)}/{sum(r['method'] == m for r in rows)}"}
        for k in GOALS:
            v = np.array([r[k] for r in ok]) if ok else np.array([np.nan])
            t[f"{k} median"], t[f"{k} worst"] = float(np.median(v)), float(np.max(v))
        if ok and "rot_sigma_deg" in ok[0]:
            t["sigma rot_deg, trans_mm (median)"] = (f"{np.median([r['rot_sigma_deg'] for r in ok]):.4f}, "
                                                     f"{np.median([r['trans_sigma_mm'] for r in ok]):.4f}")
        out.append(t)
    out.append({"method": "goal (issue 25)", **{f"{k} median": v for k, v in GOALS.items()}})
    return out


def trust_table(noise: list[dict[str, Any]], sessions: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per quantity: spread / sigma and max |err| / sigma over noise draws; z spread and max |z|
    over new sessions (module docstring)."""
    ok = [r for r in noise if "error" not in r]
    ses = [r for r in sessions if "error" not in r]
    rows = []
    for q in QUANTITIES:
        est = np.array([r["est"][q] for r in ok])
        sig = np.array([r["sigma"][q] for r in ok])
        err = np.array([r["err"][q] for r in ok])
        z = np.array([r["err"][q] / r["sigma"][q] for r in ses])
        sigma = float(np.mean(sig)) if len(sig) else float("nan")
        rows.append({"quantity": q, "unit": "deg" if q.startswith("rot") else "mm" if q.startswith("t_") else "px",
                     "sigma": sigma, "draws": len(ok),
                     "spread_over_sigma": float(np.std(est, ddof=1) / sigma) if len(est) > 1 else float("nan"),
                     "max_abs_err_over_sigma": float(np.max(np.abs(err) / sig)) if len(err) else float("nan"),
                     "bias_over_sigma": float(np.mean(err) / sigma) if len(err) else float("nan"),
                     "sessions": len(ses),
                     "z_spread_sessions": float(np.std(z, ddof=1)) if len(z) > 1 else float("nan"),
                     "max_abs_z_sessions": float(np.max(np.abs(z))) if len(z) else float("nan")})
    return rows


def stereo_study(out: Path, views: int = 15, seed: int = 1, draws: int = 10, sessions: int = 5,
                 workers: int = 2) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Both tables (CSV, JSON, Markdown in ``out``): accuracy over ``sessions`` sessions (seeds
    ``seed`` .. ``seed + sessions - 1``), trust over ``draws`` noise draws of the session of
    ``seed`` and ``draws`` new sessions (0: no trust table)."""
    sys.stderr.write(f"stereo: {sessions} sessions of {views} shots, ours and OpenCV ...\n")
    with ProcessPoolExecutor(workers) as pool:
        acc = [r for rows in pool.map(_accuracy_job, [(views, seed + k) for k in range(sessions)]) for r in rows]
        jobs = [(views, seed, d, "noise") for d in range(draws)] + [(views, seed, d, "session") for d in range(draws)]
        if draws:
            sys.stderr.write(f"stereo: {draws} noise draws and {draws} new sessions ...\n")
        trust = list(pool.map(_trust_job, jobs))
    per_session = [{k: v for k, v in r.items() if k not in ("signed", "sigma", "est", "err")} for r in acc]
    write_rows(per_session, out, "stereo_sessions")
    table = accuracy_table(acc)
    write_rows(table, out, "stereo_accuracy")
    ttable = trust_table(trust[:draws], trust[draws:]) if draws else []
    if ttable:
        write_rows(ttable, out, "stereo_trust")
    return table, ttable
