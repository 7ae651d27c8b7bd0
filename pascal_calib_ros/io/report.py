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

from ..calibrate.diagnostics import distortion_field, observed_field_mask, view_hulls
from ..calibrate.pipeline import CalibrationResult
from ..detect.detection import Detection

FIELD_MARGIN = 30.0  # px around the observed field where the distortion field is still drawn


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


def _observed_field(res: CalibrationResult, margin: float = 0.0) -> np.ndarray:
    return observed_field_mask(res.edge_points, res.width, res.height, margin)


def report_numbers(res: CalibrationResult, dets: list[Detection]) -> dict[str, Any]:
    cam = res.camera()
    _, disp = distortion_field(cam, mask=_observed_field(res, FIELD_MARGIN))
    mag = np.linalg.norm(disp, axis=1) if len(disp) else np.zeros(1)
    covered = float(_observed_field(res).mean()) if res.edge_points else 0.0
    return {
        "image": {"width": res.width, "height": res.height},
        "method": res.method, "refined": res.refined, "distortion_model": res.model,
        "distortion_choice": res.distortion_model,
        "K": res.K.tolist(), "D": res.D.tolist(), "std": res.std,
        "rms_px": res.rms, "degeneracy_ratio": res.degeneracy_ratio, "warnings": res.warnings,
        "views": [{"name": v.name, "used": v.used, "reason": v.reason, "rms_px": v.rms, "edge_offset_px": v.edge_offset}
                  for v in res.views],
        "residuals": {"per_view_rms_px": [float(np.sqrt(np.mean(r * r))) for r in res.edge_residuals],
                      "per_circle_rms_px": per_circle_rms(res),
                      "max_abs_px": float(max((np.max(np.abs(r)) for r in res.edge_residuals), default=0.0))},
        "coverage": {"observed_fraction": covered, "image_fraction_inside_some_view": covered,
                     "view_hulls": [np.round(h, 2).tolist() for h in view_hulls(res.edge_points)]},
        "distortion_field": {"over": f"observed field + {FIELD_MARGIN:.0f} px", "max_px": float(mag.max()),
                             "mean_px": float(mag.mean())},
        "uncertainty": {"projection": res.projection_summary(),
                        "projection_over": "observed field, worst-direction sigma (mrcal's projection uncertainty)",
                        "std_model": "sandwich covariance, per-view noise, correlated edge residuals"},
        "target_shape": {"estimated": {n: res.shape[n] for n in res.shape_std}, "std": res.shape_std,
                         "change_against_flat_sheet": res.shape_effect} if res.shape else None,
    }


def _wrapped(warnings: list[str], width: int = 70) -> list[str]:
    """Every warning in full, wrapped to ``width`` characters."""
    import textwrap

    out = ["warnings:" if warnings else "no warnings"]
    for x in warnings:
        out += [*textwrap.wrap(x, width, initial_indent="- ", subsequent_indent="  "), ""]
    return out


def write_report(res: CalibrationResult, dets: list[Detection], out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``report.png`` and ``report.json`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    numbers = report_numbers(res, dets)
    (out / "report.json").write_text(json.dumps(numbers, indent=1, default=float))

    fig, ax = plt.subplots(2, 3, figsize=(20, 11))
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
    field = _observed_field(res)
    if field.any():
        for axx in (b, ax[1][0]):
            axx.contour(field.astype(float), levels=[0.5], colors="k", linewidths=1.0, linestyles="--")
    b.set_title(f"coverage: {100 * numbers['coverage']['observed_fraction']:.0f} % of the image "
                f"in the observed field (dashed; {res.n_used} views)")
    # distortion field, over the observed field only (a fold outside it must not set the scale)
    c = ax[1][0]
    uv, disp = distortion_field(res.camera(), mask=_observed_field(res, FIELD_MARGIN))
    if not len(uv):
        uv, disp = np.zeros((1, 2)), np.zeros((1, 2))
    mag = np.linalg.norm(disp, axis=1)
    arrow = max(float(mag.max()) / 28.0, 1e-9)  # the longest arrow spans about one grid step
    q = c.quiver(uv[:, 0], uv[:, 1], disp[:, 0], disp[:, 1], mag, angles="xy", scale_units="xy", scale=arrow,
                 cmap="viridis")
    fig.colorbar(q, ax=c, label="displacement (px)")
    c.plot(res.K[0, 2], res.K[1, 2], "r+", ms=15)
    c.set_title(f"{res.model} distortion against its ideal lens, observed field\n"
                f"(arrows x{1 / arrow:.2g}; max {mag.max():.1f} px); + principal point", fontsize=10)
    for axx in (a, b, c):
        axx.set_xlim(0, w)
        axx.set_ylim(h, 0)
        axx.set_aspect("equal")
    # projection uncertainty, observed field dashed
    e = ax[1][1]
    pu = res.projection
    if pu is not None:
        im = e.imshow(pu.sigma.reshape(pu.grid_shape), extent=(0, w, h, 0), cmap="magma",
                      vmax=float(np.nanpercentile(pu.sigma, 95)) if np.isfinite(pu.sigma).any() else None)
        fig.colorbar(im, ax=e, label="projection sigma (px)")
        if field.any():
            e.contour(field.astype(float), levels=[0.5], colors="c", linewidths=1.0, linestyles="--")
        e.set_title(f"{res.projection_line()}".replace(" in the observed", "\nin the observed"), fontsize=10)
    else:
        e.set_title("projection uncertainty: not available")
    e.set_xlim(0, w)
    e.set_ylim(h, 0)
    e.set_aspect("equal")
    ax[0][2].axis("off")
    # parameters
    d_ax = ax[1][2]
    d_ax.axis("off")
    names = ["fx", "fy", "cx", "cy", *res.camera().lens.coefficients]
    vals = [res.K[0, 0], res.K[1, 1], res.K[0, 2], res.K[1, 2], *res.D]
    lines = [f"method {res.method}{' + refinement' if res.refined else ''}, {res.n_used}/{len(res.views)} views",
             f"RMS {res.rms:.4f} px, degeneracy ratio {res.degeneracy_ratio:.3f}", ""]
    lines += [f"{n:>3} = {v:12.5f}  +- {res.std.get(n, float('nan')):.5f}" for n, v in zip(names, vals, strict=True)]
    if res.shape_std:
        lines += ["target shape: " + ", ".join(f"{n} {res.shape[n]:+.2e}" for n in res.shape_std)]
    lines += [""] + [f"{v.name}: {f'used, rms {v.rms:.3f} px' if v.used else 'rejected: ' + v.reason}"[:70]
                     for v in res.views[:18]]
    d_ax.text(0, 1, "\n".join(lines), va="top", family="monospace", fontsize=9)
    ax[0][2].text(0, 1, "\n".join(_wrapped(res.warnings)), va="top", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "report.png", dpi=80)
    plt.close(fig)
    return out / "report.png", out / "report.json"
