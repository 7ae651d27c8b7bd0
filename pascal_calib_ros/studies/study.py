"""Accuracy studies against ground truth (``pascal-calib study NAME``); figures in the README.

- ``accuracy``: ring-only calibration (closed form + refinement) against OpenCV
  ``calibrateCamera`` on a checkerboard rendered from the same poses, per scenario.
- ``edge-bias``: what the edge-bias handling is worth (per-view offset, gamma linearisation,
  curvature correction), on one realistic scenario.
- ``grids``: ring and disc grids under strong distortion, beside OpenCV's circle-grid finder.
- ``target-shape``: sheets printed off scale or not flat, calibrated with and without the
  estimated target shape.
- ``lenses``: a ~180 degree fisheye (equidistant) and a ~120 degree rational wide-angle lens:
  ring and disc grids with the matching model beside OpenCV (fisheye.calibrate, calibrateCamera
  with the rational model) on a checkerboard from the same poses; plumb_bob on the fisheye.
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibrate import CalibrationError, CalibrationOptions, calibrate
from ..detect import DetectionParams, detect_target
from ..geometry import Camera, calibration_errors, observed_field_mask
from ..sim import SessionSpec, features_in_image, render_session_views, render_view, session_views
from ..targets import resolve_target


@dataclass(frozen=True)
class Scenario:
    name: str
    spec: SessionSpec


SCENARIOS = (
    Scenario("800x600, no distortion", SessionSpec(width=800, height=600, blur=1.0)),
    Scenario("800x600, k1=-0.3", SessionSpec(width=800, height=600, k1=-0.3, blur=1.0)),
    Scenario("800x600, k1=-0.3, blur 1.5, JPEG 90", SessionSpec(width=800, height=600, k1=-0.3, blur=1.5, jpeg=90)),
    Scenario("1920x1080, k1=-0.3", SessionSpec(width=1920, height=1080, k1=-0.3, blur=1.2)),
    Scenario("2456x2058, k1=-0.2", SessionSpec(width=2456, height=2058, k1=-0.2, blur=1.2)),
)


def _errors(truth: Camera, K: np.ndarray, D: np.ndarray) -> dict[str, float]:
    """The study tables' columns of :func:`calibration_errors`."""
    e = calibration_errors(truth, K, D)
    return {k: e[k] for k in ("fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px")}


def _render_pair(spec: SessionSpec, seed: int) -> tuple[Camera, list[np.ndarray], list[np.ndarray]]:
    """Ring and checkerboard images from the same poses (poses chosen with the larger board)."""
    ring, board = resolve_target("ring_a4"), resolve_target("checkerboard_a4")
    spec = replace(spec, seed=seed)
    cam = spec.camera()
    ring_imgs, board_imgs = [], []
    for _, pose, sens in session_views(board, spec):
        ring_imgs.append(render_view(ring, cam, pose, sens).image)
        board_imgs.append(render_view(board, cam, pose, sens).image)
    return cam, ring_imgs, board_imgs


def accuracy(out: Path, views: int, seed: int) -> list[dict[str, Any]]:
    ring, board = resolve_target("ring_a4"), resolve_target("checkerboard_a4")
    rows: list[dict[str, Any]] = []
    for sc in SCENARIOS:
        sys.stderr.write(f"rendering {sc.name} ...\n")
        cam, ring_imgs, board_imgs = _render_pair(replace(sc.spec, views=views), seed)
        ring_dets = [detect_target(im, ring, name=f"v{k}") for k, im in enumerate(ring_imgs)]
        board_dets = [detect_target(im, board, name=f"v{k}") for k, im in enumerate(board_imgs)]
        for label, dets, target, opt in (
            ("ring closed form", ring_dets, ring, CalibrationOptions(refine=False)),
            ("ring refined", ring_dets, ring, CalibrationOptions()),
            ("OpenCV checkerboard", board_dets, board, CalibrationOptions(method="zhang", refine=False)),
            ("checkerboard refined (ours)", board_dets, board, CalibrationOptions(method="zhang")),
        ):
            try:
                res = calibrate(dets, target, opt)
                err = _errors(cam, res.K, res.D)
                rows.append({"scenario": sc.name, "method": label, "views": res.n_used, **err, "rms": res.rms})
            except CalibrationError as e:
                rows.append({"scenario": sc.name, "method": label, "views": 0, "error": str(e)})
        rows.append({"scenario": sc.name, **_opencv_own_board(cam, board, board_imgs)})
    write_rows(rows, out, "accuracy")
    return rows


def _opencv_own_board(cam: Camera, board: Any, imgs: list[np.ndarray]) -> dict[str, Any]:
    """What OpenCV users get on the same checkerboard renders: their corners
    (``findChessboardCornersSB`` + ``cornerSubPix``, :func:`opencv_board_corners`) and
    ``cv2.calibrateCamera`` with its default model (k1, k2, p1, p2, k3), one thread."""
    import cv2

    cb = board.checkerboards[0]
    obj = np.c_[cb.corner_points(), np.zeros(len(cb.corner_points()))].astype(np.float32)
    found = [c for c in (opencv_board_corners(im, cb.inner_corners, True) for im in imgs) if c is not None]
    label = "OpenCV's own (SB + cornerSubPix, calibrateCamera)"
    if len(found) < MIN_VIEWS_OPENCV:
        return {"method": label, "views": len(found), "error": "board found in fewer than 3 views"}
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        rms, K, D, _, _ = cv2.calibrateCamera([obj] * len(found), [c.astype(np.float32) for c in found],
                                              (cam.width, cam.height), None, None)
    finally:
        cv2.setNumThreads(threads)
    return {"method": label, "views": len(found), **_errors(cam, K, np.asarray(D).ravel()), "rms": float(rms)}


def edge_bias(out: Path, views: int, seed: int) -> list[dict[str, Any]]:
    ring = resolve_target("ring_a4")
    spec = SessionSpec(width=800, height=600, k1=-0.3, blur=1.2, gamma=2.2, views=views, seed=seed)
    cam = spec.camera()
    imgs = [render_view(ring, cam, pose, sens).image for _, pose, sens in session_views(ring, spec)]
    variants = (
        ("no bias handling", DetectionParams(), False),
        ("per-view edge offset (default)", DetectionParams(), True),
        ("gamma linearised (known 2.2), no offset", DetectionParams(gamma=2.2), False),
        ("gamma linearised + offset", DetectionParams(gamma=2.2), True),
        ("offset, no curvature correction", DetectionParams(curvature_correction=False), True),
        ("no offset, no curvature correction", DetectionParams(curvature_correction=False), False),
    )
    rows: list[dict[str, Any]] = []
    for label, params, offsets in variants:
        dets = [detect_target(im, ring, params) for im in imgs]
        try:
            res = calibrate(dets, ring, CalibrationOptions(edge_offsets=offsets))
            rows.append({"variant": label, **_errors(cam, res.K, res.D), "rms": res.rms,
                         "mean_offset_px": float(np.nanmean([v.edge_offset for v in res.views if v.used]))})
        except CalibrationError as e:
            rows.append({"variant": label, "error": str(e)})
    write_rows(rows, out, "edge_bias")
    return rows


def grids(out: Path, views: int, seed: int) -> list[dict[str, Any]]:
    """Grid boards on a strongly distorting 1024x768 camera (k1 = -0.43): ours (every edge point
    against its projected circle) beside OpenCV findCirclesGrid + calibrateCamera (blob centroids)
    on the same renders."""
    import time

    import cv2

    rows: list[dict[str, Any]] = []
    for name, jpeg in (("disc_grid_a4", 0), ("ring_grid_a4", 0), ("disc_grid_a4", 90)):
        target = resolve_target(name)
        spec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=max(views, 20), blur=1.0, jpeg=jpeg,
                           seed=seed, size_range=(0.45, 0.9), tilt_range=(10, 45))
        cam = spec.camera()
        imgs = [render_view(target, cam, pose, sens).image for _, pose, sens in session_views(target, spec)]
        label = f"{name}{', JPEG 90' if jpeg else ''}"
        t0 = time.perf_counter()
        dets = [detect_target(im, target) for im in imgs]
        t_det = (time.perf_counter() - t0) / len(imgs)
        t0 = time.perf_counter()
        try:
            res = calibrate(dets, target)
            rows.append({"target": label, "method": "pascal-calib (edges, conics)", "views": res.n_used,
                         **_errors(cam, res.K, res.D), "rms": res.rms, "detect_ms": 1000 * t_det,
                         "calibrate_s": time.perf_counter() - t0})
        except CalibrationError as e:
            rows.append({"target": label, "method": "pascal-calib (edges, conics)", "views": 0, "error": str(e)})
        g = target.grids[0]
        if g.kind != "disc":
            continue  # OpenCV's circle-grid detector finds blobs, not rings
        obj = np.c_[g.centers(), np.zeros(g.rows * g.cols)].astype(np.float32)
        ops, ips = [], []
        for im in imgs:
            ok, centres = cv2.findCirclesGrid(im, (g.cols, g.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
            if ok:
                ops.append(obj)
                ips.append(centres)
        if len(ops) >= 3:
            _, K, D, _, _ = cv2.calibrateCamera(ops, ips, (1024, 768), None, None)
            rows.append({"target": label, "method": "OpenCV findCirclesGrid + calibrateCamera (centroids)",
                         "views": len(ops), **_errors(cam, np.asarray(K), np.asarray(D).ravel()[:5])})
        else:
            rows.append({"target": label, "method": "OpenCV findCirclesGrid + calibrateCamera (centroids)",
                         "views": len(ops), "error": "grid found in fewer than 3 views"})
    write_rows(rows, out, "grids")
    return rows


SHAPE_SCENARIOS = (
    ("flat, true to scale", 0.0, 0.0, 0.0),
    ("y printed 0.3 % long", 0.003, 0.0, 0.0),
    ("bent: 1.5 mm / 0.8 mm", 0.0, 0.0015, 0.0008),
    ("0.3 % long and bent", 0.003, 0.0015, 0.0008),
)


def target_shape(out: Path, views: int, seed: int) -> list[dict[str, Any]]:
    """Ring grid, 1024x768, k1 = -0.43, 20 views, on sheets of known shape (render.SheetShape):
    the nominal flat model beside the estimated shape (refine.SHAPE_NAMES), errors against truth."""
    from ..calibrate import SHAPE_CHOICES

    target = resolve_target("ring_grid_a4")
    rows: list[dict[str, Any]] = []
    for label, ratio, wx, wy in SHAPE_SCENARIOS:
        spec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=max(views, 20), blur=1.0, seed=seed,
                           size_range=(0.45, 0.9), tilt_range=(10, 45), pitch_ratio=ratio, warp_x=wx, warp_y=wy)
        cam, views_ = render_session_views(target, spec)  # rendered on the bent, scaled sheet
        dets = [detect_target(v.image, target) for v in views_]
        for estimate in ("", "warp", "all"):
            opts = CalibrationOptions(target_shape=SHAPE_CHOICES[estimate])
            model = f"target shape: {estimate}" if estimate else "flat, nominal"
            row: dict[str, Any] = {"sheet": label, "model": model}
            try:
                res = calibrate(dets, target, opts)
            except CalibrationError as e:
                rows.append({**row, "error": str(e)})
                continue
            row.update({**_errors(cam, res.K, res.D), "rms": res.rms})
            if estimate:
                row.update({"pitch_ratio_pct": 100 * res.shape["pitch_ratio"] if "pitch_ratio" in res.shape_std else 0,
                            "warp_x_mm": 1000 * res.shape["warp_x"], "warp_y_mm": 1000 * res.shape["warp_y"],
                            "warned": any("target shape matters" in w for w in res.warnings)})
                if "pitch_ratio" in res.shape_std:
                    row["pitch_aspect_corr"] = res.shape_effect["pitch_aspect_correlation"]
            rows.append(row)
    write_rows(rows, out, "target_shape")
    return rows


def write_rows(rows: list[dict[str, Any]], out: Path, name: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(out / f"{name}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    (out / f"{name}.json").write_text(json.dumps(rows, indent=1))
    print(markdown_table(rows, keys))
    print(f"\nwrote {out / name}.csv")


def markdown_table(rows: list[dict[str, Any]], keys: list[str]) -> str:
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4f}" if abs(v) < 10 else f"{v:.1f}"
        return str(v)

    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


@dataclass(frozen=True)
class LensCase:
    name: str
    spec: SessionSpec
    distortion: str  # CalibrationOptions.distortion of the matching model


def lens_cases(views: int, seed: int) -> tuple[LensCase, ...]:
    """The two lenses of :func:`lenses`, 1024x768: an equidistant fisheye of 300 px focal length
    (190 degrees across the width, 143 down the height, rays up to 124 degrees in the corners) and
    a rational wide-angle lens of 500 px whose model is monotonic up to 57.5 degrees from the axis
    (115 degrees across an image circle of radius about 430 px). Targets are placed out to 5 % of
    the image border so that some fisheye views reach beyond 90 degrees."""
    base = SessionSpec(width=1024, height=768, views=views, seed=seed, pixel_range=(0.05, 0.95),
                       size_range=(0.25, 0.5))
    return (
        LensCase("fisheye 190 deg (equidistant)",
                 replace(base, focal=300, lens="equidistant", dist=(0.02, -0.005, 0.001, -0.0002)), "equidistant"),
        LensCase("wide-angle 115 deg (rational)",
                 replace(base, focal=500, lens="rational_polynomial",
                         dist=(0.6, -0.05, 0.0005, -0.0003, 0.0, 0.95, 0.1, 0.0)), "rational_polynomial"),
    )


LENS_COLUMNS = ("lens", "target", "method", "views", "fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px",
                "model_err_our_field_px", "rms", "max_ray_deg", "views_beyond_90", "field_pct", "note", "error")


def _ray_angles_deg(cam: Camera, pixels: np.ndarray) -> np.ndarray:
    """Angle from the optical axis (degrees) of the true rays of pixels (N, 2)."""
    rays = cam.unproject(np.asarray(pixels, float).reshape(-1, 2))
    return np.degrees(np.arccos(np.clip(rays[:, 2], -1.0, 1.0)))


def _lens_row(case: LensCase, target: str, method: str, **values: Any) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(LENS_COLUMNS, "")
    row.update(lens=case.name, target=target, method=method, **values)
    return row


def _masked_errors(cam: Camera, K: np.ndarray, D: np.ndarray, model: str, mask: np.ndarray) -> dict[str, float]:
    e = calibration_errors(cam, K, D, model, mask=mask)
    return {k: e[k] for k in ("fx_err_pct", "fy_err_pct", "pp_err_px", "model_err_px")}


def _ours(case: LensCase, cam: Camera, imgs: list[np.ndarray], target_name: str, distortion: str,
          method: str) -> tuple[dict[str, Any], np.ndarray | None]:
    """Our calibration of one grid session; the row and the observed field (None on failure)."""
    target = resolve_target(target_name)
    dets = [detect_target(im, target, name=f"v{k}") for k, im in enumerate(imgs)]
    try:
        res = calibrate(dets, target, CalibrationOptions(distortion=distortion))
    except CalibrationError as e:
        return _lens_row(case, target_name, method, views=f"0/{len(imgs)}", error=str(e)), None
    mask = observed_field_mask(res.edge_points, cam.size)
    angles = [float(_ray_angles_deg(cam, p).max()) for p in res.edge_points]
    rejected = sorted({v.reason for v in res.views if not v.used and v.reason})
    row = _lens_row(case, target_name, method, views=f"{res.n_used}/{len(imgs)}",
                    **_masked_errors(cam, res.K, res.D, res.model, mask), rms=res.rms,
                    max_ray_deg=max(angles), views_beyond_90=sum(a > 90 for a in angles),
                    field_pct=100 * float(mask.mean()), note="; ".join(rejected))
    return row, mask


def opencv_board_corners(img: np.ndarray, board_size: tuple[int, int], subpix: bool) -> np.ndarray | None:
    """(N, 2) inner corners by ``cv2.findChessboardCornersSB`` (exhaustive, accuracy passes),
    mirrored orders flipped to the sheet's handedness (the 180 degree ambiguity is a rigid motion
    of the board, harmless for calibration); with ``subpix``, then refined by ``cv2.cornerSubPix``
    with a window per corner fitted to its squares (detect/checkerboard.refine_corners: a fixed
    window would swallow the small outer squares of a fisheye view)."""
    import cv2

    from ..detect import refine_corners, right_handed

    nx, ny = board_size
    found, c = cv2.findChessboardCornersSB(
        img, (nx, ny), flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if not found or c is None:
        return None
    grid = right_handed(np.asarray(c, float).reshape(ny, nx, 2))
    if subpix:
        grid = refine_corners(img, grid)
    return grid.reshape(-1, 2)


MIN_VIEWS_OPENCV = 3


def cv_flag(name: str) -> int:
    """An OpenCV calibration flag: ``cv2.fisheye.NAME`` up to 4.x, ``cv2.NAME`` in 5.0."""
    import cv2

    return int(getattr(cv2.fisheye, name, getattr(cv2, name)))


def _opencv_fisheye(obj: np.ndarray, ips: list[np.ndarray], size: tuple[int, int]
                    ) -> tuple[float, np.ndarray, np.ndarray, list[int], list[int]]:
    """``cv2.fisheye.calibrate`` from an intrinsic guess (f = width / pi, i.e. 180 degrees across
    the width; centred principal point), with CALIB_CHECK_COND: a view OpenCV names as
    ill-conditioned is dropped and the calibration repeated. Returns rms, K, D, the indices (into
    ``ips``) used and those dropped. OpenCV 5.0 wants the points as (1, N, 3) and (1, N, 2) arrays:
    the (N, 1, 3) layout of the 4.x samples fails in arithm_op ("Sizes of input arguments do not
    match")."""
    import re

    import cv2

    w, h = size
    flags = (cv_flag("CALIB_USE_INTRINSIC_GUESS") | cv_flag("CALIB_RECOMPUTE_EXTRINSIC")
             | cv_flag("CALIB_FIX_SKEW") | cv_flag("CALIB_CHECK_COND"))
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    keep = list(range(len(ips)))
    dropped: list[int] = []
    while len(keep) >= MIN_VIEWS_OPENCV:
        K0 = np.array([[w / np.pi, 0.0, w / 2], [0.0, w / np.pi, h / 2], [0.0, 0.0, 1.0]])
        try:
            rms, K, D, _, _ = cv2.fisheye.calibrate(
                [obj.reshape(1, -1, 3)] * len(keep), [ips[k].reshape(1, -1, 2) for k in keep], (w, h), K0,
                np.zeros(4), flags=flags, criteria=criteria)
            return float(rms), np.asarray(K), np.asarray(D).ravel()[:4], keep, dropped
        except cv2.error as e:
            m = re.search(r"input array (\d+)", str(e))
            if m is None:
                raise
            dropped.append(keep.pop(int(m.group(1))))
    raise cv2.error(f"fewer than {MIN_VIEWS_OPENCV} views left after CALIB_CHECK_COND dropped {len(dropped)}")


def _opencv_rows(case: LensCase, cam: Camera, poses: list[Any], sensors: list[Any],
                 our_field: np.ndarray | None) -> list[dict[str, Any]]:
    """OpenCV on checkerboard_a4 rendered from the grid session's poses with the same camera
    (views where the board is not wholly in the image skipped), corners by
    findChessboardCornersSB with and without cornerSubPix, the lens's model in OpenCV."""
    import cv2

    board_t = resolve_target("checkerboard_a4")
    board = board_t.checkerboards[0]
    n = len(poses)
    in_view = [k for k, p in enumerate(poses) if features_in_image(board_t, cam, p, margin=3.0)]
    imgs = {k: render_view(board_t, cam, poses[k], sensors[k]).image for k in in_view}
    obj2 = board.corner_points()
    obj = np.c_[obj2, np.zeros(len(obj2))]
    rows: list[dict[str, Any]] = []
    fisheye = case.distortion == "equidistant"
    for subpix in (False, True):
        method = "OpenCV " + ("fisheye.calibrate" if fisheye else "calibrateCamera RATIONAL") + \
            (", SB + cornerSubPix" if subpix else ", SB corners")
        found = {}
        for k in in_view:
            c = opencv_board_corners(imgs[k], board.inner_corners, subpix)
            if c is not None:
                found[k] = c
        ks = sorted(found)
        note = f"board wholly in view {len(in_view)}/{n}, found {len(ks)}"
        if len(ks) < MIN_VIEWS_OPENCV:
            rows.append(_lens_row(case, "checkerboard_a4", method, views=f"0/{n}", note=note,
                                  error="board found in fewer than 3 views"))
            continue
        ips = [found[k] for k in ks]
        try:
            if fisheye:
                rms, K, D, used, dropped = _opencv_fisheye(obj, ips, (cam.width, cam.height))
                model = "equidistant"
                if dropped:
                    ang = [_true_ray_angle(cam, poses[ks[j]], obj) for j in dropped]
                    note += (f", CALIB_CHECK_COND dropped {len(dropped)} (their corners reach "
                             + ", ".join(f"{a:.0f}" for a in sorted(ang)) + " deg)")
            else:
                rms, K, D, _, _ = cv2.calibrateCamera(
                    [obj.astype(np.float32)] * len(ks), [p.astype(np.float32) for p in ips],
                    (cam.width, cam.height), None, None, flags=cv2.CALIB_RATIONAL_MODEL)
                K, D, model = np.asarray(K), np.asarray(D).ravel()[:8], "rational_polynomial"
                used = list(range(len(ks)))
        except cv2.error as e:
            rows.append(_lens_row(case, "checkerboard_a4", method, views=f"0/{n}", note=note,
                                  error=str(e).strip().splitlines()[-1]))
            continue
        pts = [ips[j] for j in used]
        mask = observed_field_mask(pts, cam.size)
        angles = [_true_ray_angle(cam, poses[ks[j]], obj) for j in used]
        row = _lens_row(case, "checkerboard_a4", method, views=f"{len(used)}/{n}",
                        **_masked_errors(cam, K, D, model, mask), rms=float(rms), max_ray_deg=max(angles),
                        views_beyond_90=sum(a > 90 for a in angles), field_pct=100 * float(mask.mean()), note=note)
        if our_field is not None:
            row["model_err_our_field_px"] = _masked_errors(cam, K, D, model, our_field)["model_err_px"]
        rows.append(row)
    return rows


def _true_ray_angle(cam: Camera, pose: Any, obj: np.ndarray) -> float:
    """Largest angle (degrees) from the optical axis of the target points ``obj`` (N, 3) at ``pose``."""
    X = obj @ pose.R.T + pose.t
    return float(np.degrees(np.max(np.arctan2(np.hypot(X[:, 0], X[:, 1]), X[:, 2]))))


def lenses(out: Path, views: int, seed: int, cases: tuple[str, ...] = ("equidistant", "rational_polynomial")
           ) -> list[dict[str, Any]]:
    """Wide lenses (:func:`lens_cases`): the ring and disc grids calibrated with the matching model
    beside OpenCV (fisheye.calibrate or calibrateCamera with the rational model) on checkerboard_a4
    rendered from the same poses with the same camera; and plumb_bob asked of the fisheye, which
    must refuse. Errors against truth; the model error over the observed field (the union of each
    used view's convex hull of edge points or corners), for OpenCV also over our field."""
    rows: list[dict[str, Any]] = []
    for case in lens_cases(views, seed):
        if case.distortion not in cases:
            continue
        ring = resolve_target("ring_grid_a4")
        cam = case.spec.camera()
        session = session_views(ring, case.spec)
        poses = [p for _, p, _ in session]
        sensors = [s for _, _, s in session]
        sys.stderr.write(f"{case.name}: rendering {len(poses)} views of the ring and disc grids ...\n")
        ring_imgs = [render_view(ring, cam, p, s).image for p, s in zip(poses, sensors, strict=True)]
        disc = resolve_target("disc_grid_a4")
        disc_imgs = [render_view(disc, cam, p, s).image for p, s in zip(poses, sensors, strict=True)]
        ours = f"pascal-calib, {case.distortion}"
        ring_row, field = _ours(case, cam, ring_imgs, "ring_grid_a4", case.distortion, ours)
        disc_row, _ = _ours(case, cam, disc_imgs, "disc_grid_a4", case.distortion, ours)
        rows += [ring_row, disc_row]
        sys.stderr.write(f"{case.name}: OpenCV on checkerboard_a4 from the same poses ...\n")
        rows += _opencv_rows(case, cam, poses, sensors, field)
        if case.distortion == "equidistant":
            bob, _ = _ours(case, cam, ring_imgs, "ring_grid_a4", "plumb_bob", "pascal-calib, plumb_bob (wrong model)")
            rows.append(bob)
    write_rows(rows, out, "lenses")
    return rows


def run_study(name: str, out: Path, views: int | None = None, seed: int = 1) -> None:
    """Run a study; ``views`` None: 20 for ``lenses``, 15 for the others."""
    if name == "accuracy":
        accuracy(out, views or 15, seed)
    elif name == "edge-bias":
        edge_bias(out, views or 15, seed)
    elif name == "grids":
        grids(out, views or 15, seed)
    elif name == "target-shape":
        target_shape(out, views or 15, seed)
    elif name == "lenses":
        lenses(out, views or 20, seed)
    else:
        raise ValueError(f"unknown study {name!r}")
