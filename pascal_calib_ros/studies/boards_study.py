"""``pascal-calib study boards``: the marker boards people own, through our path beside OpenCV's own
on the same renders, against ground truth.

- ChArUco (``charuco_a3``, OpenCV's current pattern and the legacy one), 1280x960 with k1 = -0.3,
  whole views and views that hang partly out of the frame (:func:`~..sim.render.partial_poses`):
  ours (markers, OpenCV's corner interpolation, the saddle refinement, the edge-aware calibration)
  against OpenCV's ChArUco path as ``camera_calibration`` runs it (``CharucoDetector.detectBoard``,
  its ``cornerSubPix``, ``calibrateCamera`` with its default five coefficients).
- AprilGrid (``aprilgrid_a3``) seen by the 190 degree equidistant fisheye of the lens study
  (:func:`~.study.lens_cases`): ours against aruco's tag36h11 corners (``markerBorderBits = 2``,
  ``CORNER_REFINE_SUBPIX``) and ``cv2.fisheye.calibrate``, errors over the observed field.

Each row: views used, fx / fy error (%), principal point error (px), the model error over the whole
image (ChArUco) or the observed field (AprilGrid), the reprojection RMS, the corners measured.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..calibrate import CalibrationError, CalibrationOptions, calibrate
from ..detect import detect_target
from ..geometry import Camera, ImageSize, calibration_errors, observed_field_mask
from ..sim import SessionSpec, render_view, session_views
from ..target_boards import AprilGrid, CharucoBoard
from ..targets import Target, resolve_target
from .study import cv_flag, lens_cases, write_rows

OPENCV_MIN_CORNERS = 6  # camera_calibration's ChArUco path asks for at least this many per view


def charuco_spec(views: int, partial: int, seed: int) -> SessionSpec:
    return SessionSpec(width=1280, height=960, k1=-0.3, blur=1.0, views=views, partial_views=partial, seed=seed,
                       size_range=(0.45, 0.75))


def legacy_target(target: Target) -> Target:
    """The same board in OpenCV's legacy pattern (first square white: its rows are even)."""
    board = target.board
    assert isinstance(board, CharucoBoard)
    return replace(target, name=target.name + "_legacy", boards=(replace(board, legacy=True),))


def _ours(target: Target, imgs: list[np.ndarray], cam: Camera, distortion: str, field: bool) -> dict[str, Any]:
    dets = [detect_target(im, target, name=f"v{k}") for k, im in enumerate(imgs)]
    n = sum(int(np.isfinite(d.corners[:, 0]).sum()) for d in dets if d.ok and d.corners is not None)
    row: dict[str, Any] = {"method": "pascal-calib", "corners": n}
    try:
        res = calibrate(dets, target, CalibrationOptions(method="zhang", distortion=distortion))
    except CalibrationError as exc:
        return {**row, "views": 0, "error": str(exc)}
    mask = res.observed_field() if field else None
    e = calibration_errors(cam, res.K, res.D, res.model, mask=mask)
    return {**row, "views": f"{res.n_used}/{len(imgs)}", "rms": res.rms,
            **{k: e[k] for k in ("fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px")}}


def opencv_charuco(board: CharucoBoard, imgs: list[np.ndarray], cam: Camera) -> dict[str, Any]:
    """OpenCV's ChArUco path: detectBoard (its cornerSubPix), calibrateCamera, one thread."""
    from ..detect import charuco_detector

    detector = charuco_detector(board)
    obj_all = np.c_[board.corner_points(), np.zeros(len(board.corner_points()))].astype(np.float32)
    obj, img = [], []
    for im in imgs:
        corners, ids, _, _ = detector.detectBoard(im)
        if ids is not None and len(ids) >= OPENCV_MIN_CORNERS:
            obj.append(obj_all[np.asarray(ids).ravel()])
            img.append(np.asarray(corners, np.float32).reshape(-1, 1, 2))
    row: dict[str, Any] = {"method": "OpenCV CharucoDetector + calibrateCamera",
                           "corners": int(sum(len(o) for o in obj))}
    if len(obj) < 3:
        return {**row, "views": len(obj), "error": "board found in fewer than 3 views"}
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        rms, K, D, _, _ = cv2.calibrateCamera(obj, img, (cam.width, cam.height), None, None)
    finally:
        cv2.setNumThreads(threads)
    e = calibration_errors(cam, np.asarray(K), np.asarray(D).ravel())
    return {**row, "views": f"{len(obj)}/{len(imgs)}", "rms": float(rms),
            **{k: e[k] for k in ("fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px")}}


def aruco_aprilgrid_points(grid: AprilGrid, im: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Board points (N, 3) and pixels (N, 2) of the tags aruco finds (its sub-pixel corners)."""
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = grid.border_bits
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params)
    corners, ids, _ = det.detectMarkers(im)
    layout = grid.marker_corners()
    obj, pix = [], []
    for c, k in zip(corners, [] if ids is None else np.asarray(ids).ravel(), strict=False):
        if int(k) in layout:
            obj.append(layout[int(k)])
            pix.append(np.asarray(c, float).reshape(4, 2))
    if not obj:
        return np.zeros((0, 3)), np.zeros((0, 2))
    o = np.concatenate(obj)
    return np.c_[o, np.zeros(len(o))], np.concatenate(pix)


def opencv_fisheye_aprilgrid(grid: AprilGrid, imgs: list[np.ndarray], cam: Camera) -> dict[str, Any]:
    """aruco's tag corners and ``cv2.fisheye.calibrate`` (f = width / pi to start, CHECK_COND: a
    view it calls ill-conditioned is dropped and the calibration repeated)."""
    import re

    views = [aruco_aprilgrid_points(grid, im) for im in imgs]
    views = [v for v in views if len(v[0]) >= 8]
    row: dict[str, Any] = {"method": "OpenCV aruco tags + fisheye.calibrate", "corners": sum(len(v[0]) for v in views)}
    w, h = cam.width, cam.height
    flags = (cv_flag("CALIB_USE_INTRINSIC_GUESS") | cv_flag("CALIB_RECOMPUTE_EXTRINSIC")
             | cv_flag("CALIB_FIX_SKEW") | cv_flag("CALIB_CHECK_COND"))
    while len(views) >= 3:
        K0 = np.array([[w / np.pi, 0.0, w / 2], [0.0, w / np.pi, h / 2], [0.0, 0.0, 1.0]])
        try:
            rms, K, D, _, _ = cv2.fisheye.calibrate(
                [o.reshape(1, -1, 3) for o, _ in views], [p.reshape(1, -1, 2) for _, p in views], (w, h), K0,
                np.zeros(4), flags=flags, criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10))
        except cv2.error as e:
            m = re.search(r"input array (\d+)", str(e))
            if m is None:
                return {**row, "views": 0, "error": str(e).strip().splitlines()[-1]}
            views.pop(int(m.group(1)))
            continue
        mask = observed_field_mask([p for _, p in views], ImageSize(w, h))
        err = calibration_errors(cam, np.asarray(K), np.asarray(D).ravel()[:4], "equidistant", mask=mask)
        return {**row, "views": f"{len(views)}/{len(imgs)}", "rms": float(rms),
                **{k: err[k] for k in ("fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px")}}
    return {**row, "views": len(views), "error": "fewer than 3 views"}


def _render(target: Target, spec: SessionSpec) -> tuple[Camera, list[np.ndarray]]:
    cam = spec.camera()
    return cam, [render_view(target, cam, p, s).image for _, p, s in session_views(target, spec) if p is not None]


def boards_study(out: Path, views: int = 12, partial: int = 8, seed: int = 1) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    charuco = resolve_target("charuco_a3")
    for target in (charuco, legacy_target(charuco)):
        case = f"{target.name}, 1280x960, k1 -0.3, {views} whole + {partial} partial views"
        sys.stderr.write(f"{case}: rendering ...\n")
        cam, imgs = _render(target, charuco_spec(views, partial, seed))
        board = target.board
        assert isinstance(board, CharucoBoard)
        rows.append({"case": case, **_ours(target, imgs, cam, "plumb_bob", field=False)})
        rows.append({"case": case, **opencv_charuco(board, imgs, cam)})
    grid_t = resolve_target("aprilgrid_a3")
    fisheye = lens_cases(views, seed)[0]
    spec = replace(fisheye.spec, size_range=(0.35, 0.7), partial_views=partial)
    case = f"aprilgrid_a3, {fisheye.name}, {views} whole + {partial} partial views"
    sys.stderr.write(f"{case}: rendering ...\n")
    cam, imgs = _render(grid_t, spec)
    grid = grid_t.board
    assert isinstance(grid, AprilGrid)
    rows.append({"case": case, **_ours(grid_t, imgs, cam, "equidistant", field=True)})
    rows.append({"case": case, **opencv_fisheye_aprilgrid(grid, imgs, cam)})
    write_rows(rows, out, "boards")
    return rows

