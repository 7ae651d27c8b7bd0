"""Accuracy studies against ground truth (``pascal-calib study NAME``); figures in the README.

- ``accuracy``: ring-only calibration (closed form + refinement) against OpenCV
  ``calibrateCamera`` on a checkerboard rendered from the same poses, per scenario.
- ``edge-bias``: what the edge-bias handling is worth (per-view offset, gamma linearisation,
  curvature correction), on one realistic scenario.
- ``grids``: ring and disc grids under strong distortion, beside OpenCV's circle-grid finder.
- ``target-shape``: sheets printed off scale or not flat, calibrated with and without the
  estimated target shape.
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibrate.pipeline import CalibrationError, CalibrationOptions, calibrate
from ..detect.rings import DetectionParams, detect_target
from ..geometry.camera import Camera, calibration_errors
from ..targets import resolve_target
from .render import render_view
from .session import SessionSpec, render_session_views, session_views


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
            ("OpenCV checkerboard", board_dets, board, CalibrationOptions(method="zhang")),
        ):
            try:
                res = calibrate(dets, target, opt)
                err = _errors(cam, res.K, res.D)
                rows.append({"scenario": sc.name, "method": label, "views": res.n_used, **err, "rms": res.rms})
            except CalibrationError as e:
                rows.append({"scenario": sc.name, "method": label, "views": 0, "error": str(e)})
    _write(rows, out, "accuracy")
    return rows


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
    _write(rows, out, "edge_bias")
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
    _write(rows, out, "grids")
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
    from ..calibrate.refine import SHAPE_CHOICES

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
    _write(rows, out, "target_shape")
    return rows


def _write(rows: list[dict[str, Any]], out: Path, name: str) -> None:
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


def run_study(name: str, out: Path, views: int = 15, seed: int = 1) -> None:
    if name == "accuracy":
        accuracy(out, views, seed)
    elif name == "edge-bias":
        edge_bias(out, views, seed)
    elif name == "grids":
        grids(out, views, seed)
    elif name == "target-shape":
        target_shape(out, views, seed)
    else:
        raise ValueError(f"unknown study {name!r}")
