"""``pascal-calib bench``: detection time per frame beside one ``cv2.Canny`` pass on the same
frame, and calibration time against the number of views. Ratios, measured in the same run."""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from ..calibrate.pipeline import CalibrationOptions, calibrate
from ..detect.rings import detect_target
from ..targets import resolve_target
from .session import SessionSpec, render_session_views

SIZES = ((800, 600), (1920, 1080), (2456, 2058))


def _median_time(fn: Any, reps: int) -> float:
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def run_bench(quick: bool = False, print_table: bool = True) -> dict[str, list[dict[str, Any]]]:
    target = resolve_target("ring_a4")
    reps = 3 if quick else 15
    detect_rows = []
    for w, h in SIZES:
        spec = SessionSpec(width=w, height=h, views=3, seed=7)
        _, views = render_session_views(target, spec)
        t_det, t_canny = [], []
        for v in views:
            img = v.image
            det = detect_target(img, target)
            if not det.ok:
                raise RuntimeError(f"bench frame not detected: {det.reason}")
            t_det.append(_median_time(lambda img=img: detect_target(img, target), reps))
            t_canny.append(_median_time(lambda img=img: cv2.Canny(img, 50, 150), reps))
        row: dict[str, Any] = {"size": f"{w}x{h}", "detect_ms": 1000 * float(np.median(t_det)),
               "canny_ms": 1000 * float(np.median(t_canny))}
        row["ratio"] = row["detect_ms"] / row["canny_ms"]
        detect_rows.append(row)
        if print_table:
            print(f"detect {row['size']:>10}: {row['detect_ms']:8.2f} ms   canny {row['canny_ms']:7.2f} ms   "
                  f"ratio {row['ratio']:6.1f}x")
    # a grid frame: 70 discs at 1024x768 under strong distortion
    grid = resolve_target("disc_grid_a4")
    gspec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=20, seed=5, size_range=(0.45, 0.85),
                        tilt_range=(15, 45))
    _, gviews = render_session_views(grid, gspec)
    gimg = gviews[0].image
    row = {"size": "1024x768 grid of 70 discs",
           "detect_ms": 1000 * _median_time(lambda: detect_target(gimg, grid), reps),
           "canny_ms": 1000 * _median_time(lambda: cv2.Canny(gimg, 50, 150), reps)}
    row["ratio"] = row["detect_ms"] / row["canny_ms"]
    detect_rows.append(row)
    if print_table:
        print(f"detect {row['size']}: {row['detect_ms']:8.2f} ms   canny {row['canny_ms']:7.2f} ms")
    counts = (3, 10, 20) if quick else (3, 10, 20, 50)
    spec = SessionSpec(width=800, height=600, views=max(counts), k1=-0.2, seed=11)
    _, views = render_session_views(target, spec)
    dets = [detect_target(v.image, target) for v in views]
    cal_rows: list[dict[str, Any]] = []
    for n in counts:
        sub = dets[:n]
        t = _median_time(lambda sub=sub: calibrate(sub, target, CalibrationOptions()), 1 if quick else 3)
        cal_rows.append({"views": n, "seconds": t})
        if print_table:
            print(f"calibrate {n:3d} views (ring, refined, plumb_bob): {t:6.3f} s")
    gdets = [detect_target(v.image, grid) for v in gviews]
    t = _median_time(lambda: calibrate(gdets, grid, CalibrationOptions()), 1)
    cal_rows.append({"views": 20, "seconds": t, "target": "disc_grid_a4"})
    if print_table:
        print(f"calibrate  20 views of a 70-disc grid (plumb line + homography start, refined): {t:6.3f} s")
    return {"detect": detect_rows, "calibrate": cal_rows}
