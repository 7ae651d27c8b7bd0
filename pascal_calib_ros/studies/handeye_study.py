"""``pascal-calib study handeye``: hand-eye accuracy against ground truth on simulated arm sessions.

For each mode (eye in hand, eye to hand) one arm session of ``views`` poses (:mod:`.arm`: arm noise
0.1 mm / 0.01 deg per axis and pose plus a smooth systematic position error field of 0.25 mm per axis,
a few tenths of a millimetre as real arms have) is rendered
with each target from the same poses. Rows:

- ``ours <target>``: :func:`~..calibrate.handeye.calibrate_hand_eye` (joint estimate);
- ``park-martin <target>``: its closed-form start (Park & Martin 1994 on our per-view poses, the
  ring's linear start for a single ring) with the intrinsics of the plain calibration;
- ``opencv <method>``: OpenCV 4.x's calibrateHandEye (tsai, park, horaud, andreff, daniilidis) fed
  with the per-view poses of OpenCV's own checkerboard calibration (calibrateCamera on
  checkerboard_a4), through ``tools/opencv_handeye.py`` in the Python given by
  ``--opencv4-python`` (OpenCV 5.0 has no calibrateHandEye); not run without it.

Columns: error of X (translation mm, rotation deg), the reported sigma (norm over the axes) and
whether every axis's true error is within 3 sigma, error of fx (%) and of the principal point (px).
The arm's systematic error (:class:`~.arm.ArmSpec` ``systematic_mm``) moves X's translation by what its
gradient over the poses mimics; the jackknife part of our sigma sees it.
Writes ``handeye.json`` and ``handeye.txt`` to the output folder.
"""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..calibrate import CalibrationError
from ..calibrate.handeye import calibrate_hand_eye
from ..detect import detect_target
from ..geometry import Transform
from ..modes import HandEyeMode
from ..sim import ArmSpec, arm_poses, hand_eye_errors, render_arm_images
from ..targets import resolve_target

TOOL = Path(__file__).resolve().parents[2] / "tools" / "opencv_handeye.py"


def _k_errors(K: np.ndarray, Kt: np.ndarray) -> tuple[float, float]:
    return float(100 * (K[0, 0] / Kt[0, 0] - 1)), float(np.hypot(K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]))


def _row(name: str, X: Transform, Xt: Transform, K: np.ndarray | None, Kt: np.ndarray,
         std_mm: np.ndarray | None = None, std_deg: np.ndarray | None = None, extra: dict[str, Any] | None = None
         ) -> dict[str, Any]:
    e_mm, e_deg, dt, dr = hand_eye_errors(X, Xt)
    row: dict[str, Any] = {"method": name, "err_mm": e_mm, "err_deg": e_deg}
    if std_mm is not None and std_deg is not None:
        row["sigma_mm"] = float(np.linalg.norm(std_mm))
        row["sigma_deg"] = float(np.linalg.norm(std_deg))
        row["within_3sigma"] = bool(np.all(np.abs(dt) <= 3 * std_mm) and np.all(np.abs(dr) <= 3 * std_deg))
    if K is not None:
        row["fx_err_pct"], row["pp_err_px"] = _k_errors(K, Kt)
    row.update(extra or {})
    return row


def _opencv_rows(session: Any, mode: str, out: Path, opencv4_python: str) -> list[dict[str, Any]]:
    """OpenCV's checkerboard calibration, then calibrateHandEye in OpenCV 4.x (five methods)."""
    board_t = resolve_target("checkerboard_a4")
    imgs = session.images[board_t.name]
    board = board_t.checkerboard
    assert board is not None
    dets = [detect_target(im, board_t, name=n) for im, n in zip(imgs, session.names, strict=True)]
    used = [k for k, d in enumerate(dets) if d.corners is not None]
    obj = np.c_[board.corner_points(), np.zeros(len(board.corner_points()))].astype(np.float32)
    cam = session.camera
    pts = [np.asarray(dets[k].corners, np.float32).reshape(-1, 1, 2) for k in used]
    rms, K, _D, rvecs, tvecs = cv2.calibrateCamera([obj] * len(used), pts, (cam.width, cam.height),
                                                  None, None)
    views = []
    for j, k in enumerate(used):
        G = session.robot_poses[k]
        views.append({"R_base_tool": G.R.tolist(), "t_base_tool": G.translation.tolist(),
                      "R_cam_target": cv2.Rodrigues(rvecs[j])[0].tolist(), "t_cam_target": np.ravel(tvecs[j]).tolist()})
    inp, res_path = out / f"opencv_in_{mode}.json", out / f"opencv_out_{mode}.json"
    inp.write_text(json.dumps({"mode": mode, "views": views}))
    base = {"views": len(used), "rms_px": float(rms)}
    if not opencv4_python:
        return [{"method": "opencv (not run: give --opencv4-python)", **base, **dict(zip(
            ("fx_err_pct", "pp_err_px"), _k_errors(K, cam.K), strict=True))}]
    r = subprocess.run([opencv4_python, str(TOOL), str(inp), str(res_path)], capture_output=True, text=True,
                       timeout=300)
    if r.returncode != 0:
        return [{"method": "opencv (failed)", "error": r.stderr.strip().splitlines()[-1:] or ["?"], **base}]
    doc = json.loads(res_path.read_text())
    rows = []
    for name, m in doc["methods"].items():
        if "error" in m:
            rows.append({"method": f"opencv {name}", "error": m["error"]})
            continue
        X = Transform.from_rt(np.array(m["R"]), m["t"])
        rows.append(_row(f"opencv {doc['opencv']} {name}", X, session.hand_eye, K, cam.K, extra=base))
    return rows


def run_handeye_study(out: Path, views: int = 20, seed: int = 1, opencv4_python: str = "",
                      targets: tuple[str, ...] = ("ring_a4", "checkerboard_a4"),
                      modes: tuple[HandEyeMode, ...] = tuple(HandEyeMode),
                      systematic_mm: float = 0.25) -> list[dict[str, Any]]:
    """Run the study; ``systematic_mm`` is the arm's systematic field amplitude (0: random arm noise only)."""
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    board = resolve_target("checkerboard_a4")  # the largest sheet: keeps every target in view
    t_start = time.perf_counter()
    for mode in modes:
        session = arm_poses(ArmSpec(mode=mode, views=views, width=800, height=600, k1=-0.1, seed=seed,
                                   systematic_mm=systematic_mm), board)
        Kt = session.camera.K
        for name in dict.fromkeys((*targets, "checkerboard_a4")):
            t0 = time.perf_counter()
            target = resolve_target(name)
            imgs = render_arm_images(session, target)
            if name not in targets:
                continue
            dets = [detect_target(im, target, name=n) for im, n in zip(imgs, session.names, strict=True)]
            try:
                res = calibrate_hand_eye(dets, session.robot_poses, target, mode)
            except CalibrationError as e:
                rows.append({"mode": mode, "method": f"ours {name}", "error": str(e)})
                continue
            secs = time.perf_counter() - t0
            rows.append({"mode": mode, **_row(f"ours {name}", res.hand_eye, session.hand_eye, res.calibration.K, Kt,
                                              res.translation_std_mm, res.rotation_std_deg,
                                              {"views": res.views_used, "rms_px": res.rms_px,
                                               "robot_error_mm": res.robot_error_mm,
                                               "robot_error_deg": res.robot_error_deg, "seconds": secs})})
            if res.closed_form is not None and res.start_K is not None:
                rows.append({"mode": mode, **_row(f"park-martin {name}" if name != "ring_a4" else "ring closed form",
                                                  res.closed_form, session.hand_eye, res.start_K, Kt)})
        rows += [{"mode": mode, **r} for r in _opencv_rows(session, mode, out, opencv4_python)]
    text = format_table(rows, views, time.perf_counter() - t_start, systematic_mm)
    print(text)
    (out / "handeye.txt").write_text(text + "\n")
    (out / "handeye.json").write_text(json.dumps(rows, indent=1))
    return rows


def format_table(rows: list[dict[str, Any]], views: int, seconds: float, systematic_mm: float = 0.25) -> str:
    lines = [f"hand-eye study: {views} arm poses per mode, 800x600, arm noise 0.1 mm / 0.01 deg per axis + "
             f"systematic field {systematic_mm:g} mm per axis",
             "goals: rotation <= 0.02 deg, translation <= 0.2 mm, fx <= 0.05 %, pp <= 1 px, true error within 3 sigma",
             f"{'mode':<12} {'method':<34} {'X mm':>7} {'X deg':>7} {'sig mm':>7} {'sig deg':>7} {'3sig':>5} "
             f"{'fx %':>7} {'pp px':>6}"]

    def f(v: Any, fmt: str) -> str:
        return format(v, fmt) if isinstance(v, (int, float)) and not isinstance(v, bool) else "-"

    for r in rows:
        if "error" in r and "err_mm" not in r:
            lines.append(f"{r.get('mode', ''):<12} {r['method']:<34} {r['error']}")
            continue
        w3 = "-" if "within_3sigma" not in r else ("yes" if r["within_3sigma"] else "NO")
        lines.append(f"{r.get('mode', ''):<12} {r['method']:<34} {f(r.get('err_mm'), '7.3f')} "
                     f"{f(r.get('err_deg'), '7.4f')} {f(r.get('sigma_mm'), '7.3f')} {f(r.get('sigma_deg'), '7.4f')} "
                     f"{w3:>5} {f(r.get('fx_err_pct'), '+7.3f')} {f(r.get('pp_err_px'), '6.2f')}")
    lines.append(f"run time {seconds:.0f} s")
    return "\n".join(lines)
