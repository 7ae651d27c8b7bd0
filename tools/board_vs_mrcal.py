#!/usr/bin/env python3
"""Issue 22's benchmark: a checkerboard calibration of ours against OpenCV and mrcal on the same photos.

Usage: ``.venv/bin/python tools/board_vs_mrcal.py DIR --board BOARD.yaml [--distortion plumb_bob]
[--json OUT]`` (DIR: the photos, e.g. OpenCV's samples left01.jpg ... left14.jpg; BOARD.yaml: the
target file of that board). mrcal runs in .venv-mrcal (``make mrcal-venv``); without it its rows
say why and the rest still runs.

Rows, each on the views where its own corners were found:

- ``ours``: :func:`pascal_calib_ros.calibrate.intrinsic.pipeline.calibrate` with the target's default method,
  and ``ours, refine off`` with ``CalibrationOptions(refine=False)`` (today the default for a
  checkerboard is OpenCV's calibrateCamera, "zhang", and the two rows agree);
- ``opencv <corners>``: ``cv2.calibrateCamera`` on (a) our detector's corners, (b)
  ``findChessboardCornersSB`` (EXHAUSTIVE | ACCURACY) corners, (c) classic ``findChessboardCorners``
  + ``cornerSubPix`` (11x11) corners;
- ``mrcal``: mrcal-calibrate-cameras' solve on our corners (tools/mrcal_judge.py: outlier rejection,
  regularisation, board warp, its own noise estimate), and the same without outlier rejection.

Columns: fx fy cx cy (px), RMS (px per corner), outliers (corners rejected), projection sigma (px,
worst direction) median and worst over the observed field (the union of the views' convex hulls of
our corners) at the median distance from the camera to the board's centre (mrcal's poses) and at
infinity (ours: 1e9 m), the ratio ours / mrcal of those sigmas, and seconds (detection per view set,
calibration). Corner agreement: our corners against SB's and classic's, nearest neighbour.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pascal_calib_ros.analysis.statistics.uncertainty import ProjectionUncertainty, projection_uncertainty_of
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.calibrate.intrinsic.result import CalibrationError
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.image_field import grid_pixels, grid_shape, observed_field_mask
from pascal_calib_ros.io.images import read_grey
from pascal_calib_ros.targets import Target, resolve_target

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mrcal_bridge

from pascal_calib_ros.geometry import ImageSize

INFINITY_M = math.inf  # projection sigma at infinity (directions: the views' rotations only)
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".pgm")
SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)


def load_images(folder: Path) -> tuple[list[str], list[np.ndarray]]:
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise SystemExit(f"board_vs_mrcal: no images in {folder}")
    return [p.name for p in paths], [read_grey(p) for p in paths]


def grey8(img: np.ndarray) -> np.ndarray:
    return img if img.dtype == np.uint8 else cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))


def opencv_corners(images: list[np.ndarray], pattern: tuple[int, int], kind: str
                   ) -> tuple[list[np.ndarray | None], float]:
    """Per image the (N, 2) corners of findChessboardCornersSB ("sb") or of the classic
    findChessboardCorners + cornerSubPix ("classic"), None where not found; seconds."""
    t0 = time.perf_counter()
    out: list[np.ndarray | None] = []
    for img in images:
        g = grey8(img)
        if kind == "sb":
            ok, c = cv2.findChessboardCornersSB(g, pattern, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        else:
            ok, c = cv2.findChessboardCorners(g, pattern)
            if ok:
                c = cv2.cornerSubPix(g, c, (11, 11), (-1, -1), SUBPIX)
        out.append(np.asarray(c, float).reshape(-1, 2) if ok else None)
    return out, time.perf_counter() - t0


def row_of(name: str, K: np.ndarray, rms: float, views: int, seconds: float, **extra: Any) -> dict[str, Any]:
    return {"method": name, "fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
            "rms_px": float(rms), "views": views, "seconds": seconds, **extra}


def opencv_row(name: str, corners: list[np.ndarray | None], obj: np.ndarray, size: tuple[int, int],
               distortion: str, detect_s: float) -> dict[str, Any]:
    """cv2.calibrateCamera on the views that have corners."""
    got = [c.astype(np.float32) for c in corners if c is not None]
    flags = cv2.CALIB_RATIONAL_MODEL if distortion == "rational_polynomial" else 0
    t0 = time.perf_counter()
    rms, K, D, _, _ = cv2.calibrateCamera([obj.astype(np.float32)] * len(got), got, size, None, None, flags=flags)
    return row_of(name, K, rms, len(got), time.perf_counter() - t0, detect_s=detect_s,
                  D=np.ravel(D)[:8 if flags else 5].tolist())


def sigma_summary(pixels: np.ndarray, sigma: np.ndarray, distance: float, mask: np.ndarray) -> dict[str, float]:
    """Median and worst sigma over the grid points inside the observed field."""
    size = ImageSize.of(mask)
    pu = ProjectionUncertainty(pixels, np.asarray(sigma, float), distance, grid_shape(size, max(size) / 40.0))
    s = pu.summary(mask)
    return {"median_px": s["median_px"], "worst_px": s["worst_px"]}


def ours_rows(dets: list[Any], target: Target, distortion: str, detect_s: float) -> list[dict[str, Any]]:
    """Our pipeline with the target's default method, with the sheet's warp estimated too (as mrcal
    does by default), and with refinement off."""
    rows = []
    for name, opt in (("ours", CalibrationOptions(distortion=distortion)),
                      ("ours, --target-shape warp", CalibrationOptions(distortion=distortion,
                                                                       target_shape=("warp_x", "warp_y"))),
                      ("ours, refine off", CalibrationOptions(distortion=distortion, refine=False))):
        t0 = time.perf_counter()
        try:
            res = calibrate(dets, target, opt)
        except CalibrationError as exc:
            rows.append({"method": name, "error": str(exc)})
            continue
        row = row_of(name, res.K, res.rms, res.n_used, time.perf_counter() - t0, detect_s=detect_s,
                     D=np.ravel(res.D).tolist(), method_used=res.method, refined=res.refinement is not None,
                     outliers=sum(v.rejected_corners for v in res.views),
                     outliers_per_view=[v.rejected_corners for v in res.views if v.used],
                     kappa_corners=res.refinement.kappa[1] if res.refinement is not None else float("nan"))
        row["result"] = res  # for the sigma at mrcal's distance; dropped before printing
        rows.append(row)
    return rows


def our_sigmas(row: dict[str, Any], distance: float, mask: np.ndarray) -> None:
    """Our projection sigma at ``distance`` and at infinity over the observed field (NaN without
    a refinement: no covariance)."""
    res = row.pop("result", None)
    ref = getattr(res, "refinement", None)
    for key, d in (("sigma_dist", distance), ("sigma_inf", INFINITY_M)):
        if ref is None or ref.covariance is None:
            row[key] = {"median_px": float("nan"), "worst_px": float("nan")}
            continue
        pu = projection_uncertainty_of(ref, res.size, d)
        row[key] = sigma_summary(pu.pixels, pu.sigma, d, mask)


def mrcal_rows(corners: list[np.ndarray | None], obj: np.ndarray, size: tuple[int, int], distortion: str,
               focal: float, mask: np.ndarray) -> list[dict[str, Any]]:
    """mrcal on our corners, with its outlier rejection and without."""
    ok, why = mrcal_bridge.available()
    if not ok:
        return [{"method": "mrcal", "error": why}]
    got = [c for c in corners if c is not None]
    grid = grid_pixels(ImageSize(size[0], size[1]), max(size) / 40.0)
    rows = []
    for name, reject in (("mrcal", True), ("mrcal, no outlier rejection", False)):
        t0 = time.perf_counter()
        try:
            a = mrcal_bridge.calibrate(got, obj, size, distortion=distortion, focal=focal, grid=grid,
                                       outlier_rejection=reject)
        except mrcal_bridge.JudgeError as exc:
            rows.append({"method": name, "error": str(exc)})
            continue
        K = mrcal_bridge.K_of(a["intrinsics"])
        rows.append(row_of(name, K, a["rms_px"], len(got), time.perf_counter() - t0, D=a["intrinsics"]["D"],
                           outliers=a["n_outliers"], outliers_per_view=a["outliers_per_view"].tolist(),
                           noise_px=a["noise_px"], distance_m=a["distance_m"], std=a["std"],
                           calobject_warp=a["calobject_warp"].tolist(),
                           sigma_dist=sigma_summary(grid, a["sigma_at_distance"], a["distance_m"], mask),
                           sigma_inf=sigma_summary(grid, a["sigma_at_infinity"], INFINITY_M, mask)))
    return rows


def corner_agreement(ours: list[np.ndarray | None], other: list[np.ndarray | None]) -> dict[str, float]:
    """Nearest-neighbour distance of each of our corners to the other detector's, over the views
    both found: median, max, how many beyond 1 px."""
    d = [np.min(np.linalg.norm(a[:, None] - b[None], axis=2), 1) for a, b in zip(ours, other, strict=True)
         if a is not None and b is not None]
    if not d:
        return {"median_px": float("nan"), "max_px": float("nan"), "beyond_1px": 0, "views": 0}
    dd = np.concatenate(d)
    return {"median_px": float(np.median(dd)), "max_px": float(np.max(dd)), "beyond_1px": int(np.sum(dd > 1.0)),
            "views": len(d)}


def run(folder: Path, board: str, distortion: str) -> dict[str, Any]:
    target = resolve_target(board)
    if target.checkerboard is None:
        raise SystemExit(f"board_vs_mrcal: target {target.name!r} has no checkerboard")
    names, images = load_images(folder)
    h, w = images[0].shape[:2]
    pattern = target.checkerboard.inner_corners
    xy = target.checkerboard.corner_points()
    obj = np.c_[xy, np.zeros(len(xy))]
    t0 = time.perf_counter()
    dets = [detect_target(img, target, name=n) for n, img in zip(names, images, strict=True)]
    ours_s = time.perf_counter() - t0
    ours_c = [None if d.corners is None else np.asarray(d.corners, float) for d in dets]
    sb, sb_s = opencv_corners(images, pattern, "sb")
    classic, classic_s = opencv_corners(images, pattern, "classic")
    mask = observed_field_mask([c for c in ours_c if c is not None], ImageSize(w, h))
    rows = ours_rows(dets, target, distortion, ours_s)
    rows += [opencv_row("opencv, our corners", ours_c, obj, (w, h), distortion, ours_s),
             opencv_row("opencv, SB corners", sb, obj, (w, h), distortion, sb_s),
             opencv_row("opencv, classic + cornerSubPix", classic, obj, (w, h), distortion, classic_s)]
    focal = next(r["fx"] for r in rows if r["method"] == "opencv, our corners")  # mrcal's focal estimate
    m_rows = mrcal_rows(ours_c, obj, (w, h), distortion, focal, mask)
    distance = next((r["distance_m"] for r in m_rows if "distance_m" in r), float("nan"))
    for r in rows:
        if "result" in r:
            our_sigmas(r, distance, mask)
    rows += m_rows
    _ratios(rows)
    return {"images": names, "size": [w, h], "distortion": distortion, "board": target.name,
            "distance_m": distance, "found": {"ours": sum(c is not None for c in ours_c),
                                               "sb": sum(c is not None for c in sb),
                                               "classic": sum(c is not None for c in classic)},
            "corners_vs_sb": corner_agreement(ours_c, sb), "corners_vs_classic": corner_agreement(ours_c, classic),
            "rows": rows}


def _ratios(rows: list[dict[str, Any]]) -> None:
    """ours / mrcal of each sigma (the mrcal row with outlier rejection), for the rows that have one."""
    ref = next((r for r in rows if r["method"] == "mrcal" and "sigma_dist" in r), None)
    for r in rows:
        if ref is None or r is ref or not np.isfinite(r.get("sigma_dist", {}).get("median_px", np.nan)):
            continue
        r["ratio_to_mrcal"] = {f"{k}_{q}": r[k][q] / ref[k][q] for k in ("sigma_dist", "sigma_inf")
                               for q in ("median_px", "worst_px")}
        # mrcal takes the corners' noise as independent; ours counts their correlation along the rows and
        # columns (kappa): what remains of the ratio after sqrt(kappa) is the rest of the difference
        if "kappa_corners" in r:
            r["ratio_over_sqrt_kappa"] = {k: v / np.sqrt(r["kappa_corners"]) for k, v in r["ratio_to_mrcal"].items()}


def _f(x: Any, fmt: str = "8.3f") -> str:
    """A number in ``fmt``, or n/a in the same width."""
    if isinstance(x, (int, float)) and np.isfinite(x):
        return format(x, fmt)
    return format("n/a", ">" + fmt.split(".")[0].rstrip("dfs"))


def table(out: dict[str, Any]) -> str:
    lines = [f"{len(out['images'])} images {out['size'][0]}x{out['size'][1]}, board {out['board']}, "
             f"{out['distortion']}; corners found: ours {out['found']['ours']}, SB {out['found']['sb']}, classic "
             f"{out['found']['classic']}",
             f"projection sigma (px, worst direction) over the observed field at {out['distance_m']:.3f} m (median "
             "camera to board centre, mrcal's poses) and at infinity; ratio = this row / mrcal",
             f"{'method':32s} {'views':>5s} {'fx':>9s} {'fy':>9s} {'cx':>8s} {'cy':>8s} {'rms':>6s} {'outl':>4s} "
             f"{'s_med':>6s} {'s_max':>6s} {'si_med':>6s} {'si_max':>6s} {'ratio d med/max':>15s} "
             f"{'ratio inf med/max':>17s} {'t_det':>6s} {'t_cal':>6s}"]
    for r in out["rows"]:
        if "error" in r:
            lines.append(f"{r['method']:32s} {r['error']}")
            continue
        sd, si = r.get("sigma_dist", {}), r.get("sigma_inf", {})
        q = r.get("ratio_to_mrcal", {})
        lines.append(
            f"{r['method']:32s} {r['views']:5d} {r['fx']:9.2f} {r['fy']:9.2f} {r['cx']:8.2f} {r['cy']:8.2f} "
            f"{r['rms_px']:6.3f} {_f(r.get('outliers'), '4d')} {_f(sd.get('median_px'), '6.3f')} "
            f"{_f(sd.get('worst_px'), '6.3f')} {_f(si.get('median_px'), '6.3f')} {_f(si.get('worst_px'), '6.3f')} "
            f"{_f(q.get('sigma_dist_median_px'), '7.2f')}/{_f(q.get('sigma_dist_worst_px'), '7.2f')} "
            f"{_f(q.get('sigma_inf_median_px'), '8.2f')}/{_f(q.get('sigma_inf_worst_px'), '8.2f')} "
            f"{_f(r.get('detect_s'), '6.2f')} {r['seconds']:6.2f}")
    ref = next((r for r in out["rows"] if r["method"] == "mrcal" and "fx" in r), None)
    if ref is not None:
        lines.append("against mrcal: " + "; ".join(
            f"{r['method']}: fx {100 * (r['fx'] / ref['fx'] - 1):+.3f} %, fy {100 * (r['fy'] / ref['fy'] - 1):+.3f} %, "
            f"c ({r['cx'] - ref['cx']:+.2f}, {r['cy'] - ref['cy']:+.2f}) px"
            for r in out["rows"] if "fx" in r and r is not ref))
        lines.append(f"mrcal: noise {ref['noise_px']:.3f} px, outliers per view {ref['outliers_per_view']}, "
                     f"board warp {ref['calobject_warp']} m")
    for r in out["rows"]:
        if "ratio_over_sqrt_kappa" in r:
            q = r["ratio_over_sqrt_kappa"]
            lines.append(f"{r['method']}: outliers per view {r['outliers_per_view']}; corner kappa "
                         f"{r['kappa_corners']:.2f}; sigma ratio / sqrt(kappa) at the distance "
                         f"{q['sigma_dist_median_px']:.2f} (median) / {q['sigma_dist_worst_px']:.2f} (worst), at "
                         f"infinity {q['sigma_inf_median_px']:.2f} / {q['sigma_inf_worst_px']:.2f}")
    for k in ("corners_vs_sb", "corners_vs_classic"):
        c = out[k]
        lines.append(f"our corners vs {k[11:]}: median {c['median_px']:.3f} px, max {c['max_px']:.2f} px, "
                     f"{c['beyond_1px']} beyond 1 px ({c['views']} views)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path, help="folder of the photos")
    ap.add_argument("--board", required=True, help="target YAML of the board (or a packaged target's name)")
    ap.add_argument("--distortion", default="plumb_bob", choices=sorted(mrcal_bridge.LENSMODEL_OF_ROS))
    ap.add_argument("--json", type=Path, help="write every number here")
    a = ap.parse_args(argv)
    out = run(a.folder, a.board, a.distortion)
    print(table(out))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
