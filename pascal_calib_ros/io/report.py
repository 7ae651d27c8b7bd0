"""Calibration report: one PNG a person reads at a glance, and a JSON with the same numbers.

Panels: edge residuals of every used view (magnified vectors along the edge normal), coverage of
the image by the target across views, the distortion field (displacement in pixels between the
distorted and the ideal pinhole image), and the parameters with their standard deviations.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..calibrate.pipeline import CalibrationResult
from ..detect.rings import Detection
from ..geometry.camera import Camera


def distortion_field(cam: Camera, step: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Grid of pixels (N, 2) and the displacement (N, 2) from where an ideal pinhole camera with
    the same K would image the same ray to where the distorted camera images it."""
    us, vs = np.meshgrid(np.arange(step / 2, cam.width, step), np.arange(step / 2, cam.height, step))
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    xn = cam.undistort_pixels(uv)
    ideal = np.stack([cam.K[0, 0] * xn[:, 0] + cam.K[0, 1] * xn[:, 1] + cam.K[0, 2],
                      cam.K[1, 1] * xn[:, 1] + cam.K[1, 2]], 1)
    return uv, uv - ideal


def _normals(points: np.ndarray) -> np.ndarray:
    """Outward normals of a closed edge sampled in order (from the centroid)."""
    d = points - points.mean(0)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def per_circle_rms(res: CalibrationResult) -> dict[str, float]:
    """RMS edge residual (px) of every circle over all used views, keyed by the circle's feature
    name (``ring/outer``, ``disc_grid[2,5]`` ...) or its index; worst first."""
    if not res.edge_circles:
        return {}
    ids = np.concatenate(res.edge_circles).astype(int)
    r = np.concatenate(res.edge_residuals)
    count = np.bincount(ids)
    rms = np.sqrt(np.bincount(ids, r * r) / np.maximum(count, 1))
    names = [res.circle_names[c] if c < len(res.circle_names) else str(c) for c in range(len(count))]
    return {names[c]: float(rms[c]) for c in np.argsort(-rms) if count[c]}


def report_numbers(res: CalibrationResult, dets: list[Detection]) -> dict[str, Any]:
    cam = Camera(res.K, res.D, res.width, res.height)
    _, disp = distortion_field(cam)
    mag = np.linalg.norm(disp, axis=1)
    covered = _coverage_fraction(res, dets)
    return {
        "image": {"width": res.width, "height": res.height},
        "method": res.method, "refined": res.refined, "distortion_model": res.distortion_model,
        "K": res.K.tolist(), "D": res.D.tolist(), "std": res.std,
        "rms_px": res.rms, "degeneracy_ratio": res.degeneracy_ratio, "warnings": res.warnings,
        "views": [{"name": v.name, "used": v.used, "reason": v.reason, "rms_px": v.rms, "edge_offset_px": v.edge_offset}
                  for v in res.views],
        "residuals": {"per_view_rms_px": [float(np.sqrt(np.mean(r * r))) for r in res.edge_residuals],
                      "per_circle_rms_px": per_circle_rms(res),
                      "max_abs_px": float(max((np.max(np.abs(r)) for r in res.edge_residuals), default=0.0))},
        "coverage": {"image_fraction_inside_some_view": covered},
        "distortion_field": {"max_px": float(mag.max()), "mean_px": float(mag.mean())},
        "target_shape": {"estimated": {n: res.shape[n] for n in res.shape_std}, "std": res.shape_std,
                         "change_against_flat_sheet": res.shape_effect} if res.shape else None,
    }


def _coverage_fraction(res: CalibrationResult, dets: list[Detection]) -> float:
    import cv2

    mask = np.zeros((res.height, res.width), np.uint8)
    for d in dets:
        if d.ok and d.edges:
            cv2.fillPoly(mask, [np.round(d.edges[0].points).astype(np.int32)], 1)
    return float(mask.mean())


def write_report(res: CalibrationResult, dets: list[Detection], out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``report.png`` and ``report.json`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    numbers = report_numbers(res, dets)
    (out / "report.json").write_text(json.dumps(numbers, indent=1, default=float))

    fig, ax = plt.subplots(2, 2, figsize=(14, 11))
    w, h = res.width, res.height
    # residuals
    a = ax[0][0]
    scale = 0.05 * max(w, h) / max(max((np.max(np.abs(r)) for r in res.edge_residuals), default=1e-3), 1e-3)
    for k, (p, r) in enumerate(zip(res.edge_points, res.edge_residuals, strict=True)):
        n = _normals(p)
        a.plot(p[:, 0], p[:, 1], ",", color=f"C{k % 10}")
        a.quiver(p[::2, 0], p[::2, 1], (n[::2, 0] * r[::2]) * scale, (n[::2, 1] * r[::2]) * scale, angles="xy",
                 scale_units="xy", scale=1, width=0.0015, color=f"C{k % 10}")
    a.set_title(f"edge residuals x{scale:.0f} (RMS {res.rms:.3f} px; max {numbers['residuals']['max_abs_px']:.3f} px)")
    # coverage
    b = ax[0][1]
    for k, d in enumerate(x for x in dets if x.ok):
        for e in d.edges:
            b.plot(*np.vstack([e.points, e.points[:1]]).T, "-", lw=0.8, color=f"C{k % 10}")
    b.set_title(f"coverage: {100 * numbers['coverage']['image_fraction_inside_some_view']:.0f} % of the image "
                f"inside some view's target ({res.n_used} views)")
    # distortion field
    c = ax[1][0]
    uv, disp = distortion_field(Camera(res.K, res.D, w, h))
    mag = np.linalg.norm(disp, axis=1)
    arrow = max(float(mag.max()) / 28.0, 1e-9)  # the longest arrow spans about one grid step
    q = c.quiver(uv[:, 0], uv[:, 1], disp[:, 0], disp[:, 1], mag, angles="xy", scale_units="xy", scale=arrow,
                 cmap="viridis")
    fig.colorbar(q, ax=c, label="displacement (px)")
    c.plot(res.K[0, 2], res.K[1, 2], "r+", ms=15)
    c.set_title(f"distortion field (arrows x{1 / arrow:.2g}; max {mag.max():.1f} px); + principal point")
    for axx in (a, b, c):
        axx.set_xlim(0, w)
        axx.set_ylim(h, 0)
        axx.set_aspect("equal")
    # parameters
    d_ax = ax[1][1]
    d_ax.axis("off")
    names = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"]
    vals = [res.K[0, 0], res.K[1, 1], res.K[0, 2], res.K[1, 2], *res.D]
    lines = [f"method {res.method}{' + refinement' if res.refined else ''}, {res.n_used}/{len(res.views)} views",
             f"RMS {res.rms:.4f} px, degeneracy ratio {res.degeneracy_ratio:.3f}", ""]
    lines += [f"{n:>3} = {v:12.5f}  +- {res.std.get(n, float('nan')):.5f}" for n, v in zip(names, vals, strict=True)]
    if res.shape_std:
        lines += ["target shape: " + ", ".join(f"{n} {res.shape[n]:+.2e}" for n in res.shape_std)]
    lines += [""] + [f"{v.name}: {f'used, rms {v.rms:.3f} px' if v.used else 'rejected: ' + v.reason}"[:70]
                     for v in res.views[:18]]
    lines += [f"warning: {x}"[:80] for x in res.warnings]
    d_ax.text(0, 1, "\n".join(lines), va="top", family="monospace", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "report.png", dpi=80)
    plt.close(fig)
    return out / "report.png", out / "report.json"
