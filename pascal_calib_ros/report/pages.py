"""Calibration report: ``report.pdf`` read page by page, ``report.png`` on one page, and
``report.json`` with every number the pages show.

Pages of the PDF, in the order a person asks:
1. summary and verdict (parameters with sigma, views, projection uncertainty, the model-bias
   verdict in words, every warning);
2. coverage (each used view's outline, the observed field, views per region);
3. residuals as mrcal shows them (magnitudes; directions coloured by angle, so a lens-model bias
   shows as clusters; the mean residual per region);
4. residual statistics (mean radial residual against image radius, histogram against the
   expected noise, RMS per view);
5. the worst views on their own images with their residuals magnified (when the images are at
   hand);
6. the lens model where it holds (the distortion field over the observed field plus a margin, the
   region where the model is invertible and monotonic);
7. projection uncertainty (mrcal's, at the median target distance);
8. with a hand-eye result (``pascal-calib handeye --report``, the node with ``hand_eye``): the
   transform X with its sigma (and the arm-accuracy share of it), the arm's pose error the data
   imply, and per view the disagreement between the robot chain and the images.
The numbers come from :mod:`..analysis.residual_stats`, :mod:`..geometry.image_field` and :mod:`..geometry.model_field`.
"""

from __future__ import annotations

import json
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import MIN_EFFECTIVE, RADIAL_FLOOR_PX, REGIONAL_FLOOR_PX, Assessment, ModelBias
from ..detect import Detection
from .numbers import (
    DISTORTION_STEP,
    FIELD_MARGIN,
    VALID_STEP,
    ReportData,
    hand_eye_numbers,
    report_data,
    report_numbers,
    worst_views,
)
from .text import hand_eye_summary, projection_line, summary_lines

MAX_PLOT_POINTS = 30_000  # residual scatter plots draw at most this many points (evenly thinned)
MAGNIFY_WORST = 0.04  # the 99th percentile residual of a worst view is drawn this fraction of the image size

PAGES = 7  # 8 with a hand-eye result
ImageSource = Callable[[str], "np.ndarray | None"]  # view name -> grey image (None: not at hand)


# -- drawing -----------------------------------------------------------------------------
def _frame(ax: Any, d: ReportData, field: bool = True, colour: str = "k") -> None:
    """Image axes (y down) with the observed field dashed."""
    w, h = d.res.width, d.res.height
    if field and d.field.any():
        _outline(ax, d.field, 2, colour, "--")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect("equal")


def _outline(ax: Any, mask: np.ndarray, step: int, colour: str, style: str) -> None:
    """The boundary of a (rows, cols) bool mask sampled every ``step`` px, in pixel coordinates."""
    m = mask[::step, ::step] if mask.shape[0] > 2 * step else mask
    ys = (np.arange(m.shape[0]) + 0.5) * mask.shape[0] / m.shape[0]
    xs = (np.arange(m.shape[1]) + 0.5) * mask.shape[1] / m.shape[1]
    ax.contour(xs, ys, m.astype(float), levels=[0.5], colors=colour, linewidths=1.0, linestyles=style)


def _thin(n: int) -> np.ndarray:
    return np.arange(0, n, max(1, int(np.ceil(n / MAX_PLOT_POINTS))))


def panel_hulls(ax: Any, d: ReportData) -> None:
    for k, hull in enumerate(d.hulls):
        c = np.vstack([hull, hull[:1]])
        ax.plot(c[:, 0], c[:, 1], "-", lw=0.8, color=f"C{k % 10}")
    _frame(ax, d)
    ax.set_title(f"coverage: each used view's outline; observed field (dashed) {100 * d.field.mean():.0f} % of the "
                 "image", fontsize=9)


def panel_views_per_region(ax: Any, fig: Any, d: ReportData) -> None:
    w, h = d.res.width, d.res.height
    im = ax.imshow(d.views_per_region, extent=(0, w, h, 0), cmap="Greens", vmin=0,
                   vmax=max(int(d.views_per_region.max()), 1))
    rows, cols = d.views_per_region.shape
    for i in range(rows):
        for j in range(cols):
            ax.text((j + 0.5) * w / cols, (i + 0.5) * h / rows, str(d.views_per_region[i, j]), ha="center",
                    va="center", fontsize=7)
    fig.colorbar(im, ax=ax, label="views", fraction=0.035)
    _frame(ax, d)
    ax.set_title("views that observed each region", fontsize=9)


def panel_magnitudes(ax: Any, fig: Any, d: ReportData) -> None:
    s = d.samples
    k = _thin(len(s.points))
    mag = np.linalg.norm(s.vectors[k], axis=1)
    sc = ax.scatter(s.points[k, 0], s.points[k, 1], c=mag, s=1, cmap="inferno_r", rasterized=True,
                    vmax=float(np.percentile(mag, 99)) if len(mag) else None)
    fig.colorbar(sc, ax=ax, label="|residual| (px)", fraction=0.035)
    _frame(ax, d)
    ax.set_title(f"residual magnitudes (RMS {d.res.rms:.3f} px)", fontsize=9)


def panel_directions(ax: Any, d: ReportData) -> None:
    s = d.samples
    k = _thin(len(s.points))
    ang = np.arctan2(s.vectors[k, 1], s.vectors[k, 0])
    ax.scatter(s.points[k, 0], s.points[k, 1], c=ang, s=1, cmap="hsv", vmin=-np.pi, vmax=np.pi, rasterized=True)
    _frame(ax, d)
    ax.set_title("residual directions (colour = angle): noise looks speckled, a model bias forms clusters",
                 fontsize=9)


def _tidy(fig: Any) -> None:
    """Fixed margins (matplotlib's tight layout measures every text and costs seconds)."""
    fig.subplots_adjust(left=0.05, right=0.93, top=0.91, bottom=0.08, wspace=0.22, hspace=0.32)


def panel_regional(ax: Any, d: ReportData, labels: bool = False) -> None:
    reg, w, h = d.regional, d.res.width, d.res.height
    rows, cols = reg.grid
    cx = (np.arange(cols) + 0.5) * w / cols
    cy = (np.arange(rows) + 0.5) * h / rows
    X, Y = np.meshgrid(cx, cy)
    mag = np.linalg.norm(reg.mean, axis=1)
    tested = reg.effective >= MIN_EFFECTIVE  # regions with too few samples are drawn grey, not scaled
    scale = max(float(mag[tested].max(initial=0.0)), REGIONAL_FLOOR_PX) / (0.45 * min(w / cols, h / rows))
    biased = d.bias.biased_regions if len(d.bias.biased_regions) == len(mag) else np.zeros(len(mag), bool)
    colours = np.where(biased, "tab:red", np.where(tested, "tab:blue", "0.7"))
    ax.quiver(X.ravel(), Y.ravel(), reg.mean[:, 0], reg.mean[:, 1], color=list(colours), angles="xy",
              scale_units="xy", scale=scale, width=0.004)
    for k in range(len(mag) if labels else 0):
        ax.text(X.ravel()[k], Y.ravel()[k] + 0.38 * h / rows, f"{mag[k]:.3f} ({reg.count[k]})", ha="center",
                fontsize=5.5, color="0.3")
    for x in np.arange(1, cols) * w / cols:
        ax.axvline(x, color="0.85", lw=0.5)
    for y in np.arange(1, rows) * h / rows:
        ax.axhline(y, color="0.85", lw=0.5)
    _frame(ax, d)
    ax.set_title(f"mean residual per region, px (count); red: beyond noise and {REGIONAL_FLOOR_PX} px; grey: "
                 f"too few samples\n"
                 f"arrow of one region = {0.45 * min(w / cols, h / rows) * scale:.3f} px", fontsize=9)


def panel_radial(ax: Any, d: ReportData) -> None:
    rad = d.radial
    mid = 0.5 * (rad.edges_px[1:] + rad.edges_px[:-1])
    ok = rad.count > 0
    ax.errorbar(mid[ok], rad.mean[ok], yerr=2 * rad.stderr[ok], fmt="o-", capsize=3)
    ax.axhline(0, color="k", lw=0.8)
    for sgn in (-1, 1):
        ax.axhline(sgn * RADIAL_FLOOR_PX, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("distance from the principal point (px)")
    ax.set_ylabel("mean radial residual (px), +-2 standard errors")
    ax.set_title(f"radial residual (outwards +); dotted: {RADIAL_FLOOR_PX} px floor", fontsize=9)
    ax.grid(alpha=0.3)


def panel_histogram(ax: Any, d: ReportData, hist: dict[str, Any]) -> None:
    e = np.asarray(hist["edges_px"])
    mid = 0.5 * (e[1:] + e[:-1])
    ax.bar(mid, hist["count"], width=np.diff(e), color="tab:blue", alpha=0.6, label="residuals")
    ax.plot(mid, hist["expected"], "k-", lw=1.2, label="normal noise at each view's RMS")
    ax.set_xlabel("residual (px)")
    if np.any(np.asarray(hist["count"]) > 0):  # no residuals (--no-refine): nothing to scale
        ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.set_title("residual histogram against the expected noise", fontsize=9)


def panel_per_view(ax: Any, d: ReportData) -> None:
    worst = set(worst_views(d))
    ax.bar(range(len(d.view_rms)), d.view_rms,
           color=["tab:red" if k in worst else "tab:blue" for k in range(len(d.view_rms))])
    ax.set_xticks(range(len(d.view_rms)))
    ax.set_xticklabels([n[-18:] for n in d.used_names], rotation=90, fontsize=6)
    ax.set_ylabel("RMS (px)")
    ax.set_title("residual RMS per used view (red: the worst, drawn on the next page)", fontsize=9)


def panel_worst(ax: Any, d: ReportData, k: int, image: np.ndarray | None) -> None:
    """One used view on its own image with its residuals magnified."""
    res, s = d.res, d.samples
    sel = s.view == k
    if image is not None:
        step = max(1, int(np.ceil(max(image.shape[:2]) / 1000)))  # at most ~1000 px embedded
        ax.imshow(image[::step, ::step], cmap="gray", extent=(0, res.width, res.height, 0), rasterized=True)
    p, v = s.points[sel], s.vectors[sel]
    mag = float(np.percentile(np.linalg.norm(v, axis=1), 99)) if len(v) else 1.0
    scale = MAGNIFY_WORST * max(res.width, res.height) / max(mag, 1e-6)
    ax.plot(p[:, 0], p[:, 1], ",", color="c", rasterized=True)
    t = _thin(len(p))
    ax.quiver(p[t, 0], p[t, 1], v[t, 0] * scale, v[t, 1] * scale, color="r", angles="xy", scale_units="xy", scale=1,
              width=0.0015, rasterized=True)
    _frame(ax, d, colour="y")
    name = d.used_names[k] if k < len(d.used_names) else str(k)
    ax.set_title(f"{name}: RMS {d.view_rms[k]:.3f} px, residuals x{scale:.0f}"
                 + ("" if image is not None else " (image not at hand)"), fontsize=9)


def panel_distortion(ax: Any, fig: Any, d: ReportData) -> None:
    res = d.res
    uv, disp = (d.dist_uv, d.dist_disp) if len(d.dist_uv) else (np.zeros((1, 2)), np.zeros((1, 2)))
    mag = np.linalg.norm(disp, axis=1)
    arrow = max(float(mag.max()) / (0.9 * DISTORTION_STEP), 1e-9)  # the longest arrow spans 0.9 grid steps
    q = ax.quiver(uv[:, 0], uv[:, 1], disp[:, 0], disp[:, 1], mag, angles="xy", scale_units="xy", scale=arrow,
                  cmap="viridis")
    fig.colorbar(q, ax=ax, label="displacement (px)", fraction=0.035)
    if not d.valid_grid.all():
        v = d.valid_grid
        ys, xs = (np.arange(v.shape[0]) + 0.5) * VALID_STEP, (np.arange(v.shape[1]) + 0.5) * VALID_STEP
        ax.contourf(xs, ys, (~v).astype(float), levels=[0.5, 1.5], colors="none", hatches=["///"])
        ax.contour(xs, ys, v.astype(float), levels=[0.5], colors="r", linewidths=1.0)
    ax.plot(res.K[0, 2], res.K[1, 2], "r+", ms=12)
    _frame(ax, d)
    invalid = 100 * (1 - d.valid_grid.mean())
    ax.set_title(f"{res.model} distortion (max {mag.max():.1f} px, arrows x{1 / arrow:.2g}) over the observed "
                 f"field + {FIELD_MARGIN:.0f} px\n"
                 + (f"hatched: the model does not hold ({invalid:.1f} % of the image)" if invalid > 0
                    else "the model holds over the whole image") + "; + principal point", fontsize=9)


def panel_projection(ax: Any, fig: Any, d: ReportData) -> None:
    res = d.res
    pu = d.assessment.projection
    if pu is not None:
        sig = pu.sigma.reshape(pu.grid_shape)
        im = ax.imshow(sig, extent=(0, res.width, res.height, 0), cmap="magma",
                       vmax=float(np.nanpercentile(sig, 95)) if np.isfinite(sig).any() else None)
        fig.colorbar(im, ax=ax, label="projection sigma (px)", fraction=0.035)
        ax.set_title(projection_line(d.assessment).replace(" in the observed", "\nin the observed"), fontsize=9)
    else:
        ax.set_title("projection uncertainty: not available (no refinement)", fontsize=9)
    _frame(ax, d, colour="c")


def panel_hand_eye(ax: Any, he: Any) -> None:
    """Each view's disagreement between the robot chain and the images (translation mm, rotation
    deg x 10), beside what the arm's pose error the data imply predicts for it (the norm of three
    axes: sqrt(3) sigma); views refused by the chain check in red."""
    pv = he.per_view
    names = [v.name for v in pv]
    x = np.arange(len(pv))
    mm = np.array([v.disagreement_mm for v in pv], float)
    deg = np.array([v.disagreement_deg for v in pv], float)
    used = np.array([v.used for v in pv], bool)
    mm, deg10 = np.where(np.isfinite(mm), mm, 0.0), np.where(np.isfinite(deg), 10 * deg, 0.0)
    # the scale of the used views and of what the arm's error predicts; a refused view's bar is cut there
    # and its value written on it
    top = 1.3 * max(float(np.max(np.r_[mm[used], deg10[used], 0.0])),
                    3 * np.sqrt(3) * he.robot_error_mm, 30 * np.sqrt(3) * he.robot_error_deg, 1e-3)
    ax.bar(x - 0.2, np.minimum(mm, top), 0.4, color=np.where(used, "tab:blue", "tab:red"), label="translation (mm)")
    ax.bar(x + 0.2, np.minimum(deg10, top), 0.4, color=np.where(used, "tab:orange", "tab:red"),
           label="rotation (deg x 10)")
    for k in np.flatnonzero((mm > top) | (deg10 > top)):
        ax.text(x[k], 0.97 * top, f"{mm[k]:.1f} mm\n{deg10[k] / 10:.2f} deg", ha="center", va="top", fontsize=6,
                rotation=90, color="w")
    ax.set_ylim(0, top)
    ax.axhline(np.sqrt(3) * he.robot_error_mm, color="tab:blue", ls="--", lw=1,
               label=f"expected from the arm's error ({he.robot_error_mm:.3f} mm per axis)")
    ax.axhline(10 * np.sqrt(3) * he.robot_error_deg, color="tab:orange", ls="--", lw=1,
               label=f"expected from the arm's error ({he.robot_error_deg:.4f} deg per axis)")
    ax.set_xticks(x, names, rotation=90, fontsize=6)
    ax.set_title("robot chain vs images per view (red: refused)", fontsize=9)
    ax.legend(fontsize=7)


def _text(ax: Any, lines: list[str], fontsize: float = 8.5) -> None:
    ax.axis("off")
    ax.text(0, 1, "\n".join(lines), va="top", family="monospace", fontsize=fontsize)


@dataclass
class ReportFiles:
    png: Path
    json: Path
    pdf: Path
    model_bias: ModelBias


def write_report(a: Assessment, dets: list[Detection], out_dir: str | Path,
                 images: ImageSource | None = None, page_images: bool = False, hand_eye: Any = None
                 ) -> ReportFiles:
    """Write ``report.pdf`` (:data:`PAGES` pages, one more with ``hand_eye``, a
    :class:`~..calibrate.handeye.HandEyeResult`), ``report.png`` and ``report.json`` into
    ``out_dir``; ``images`` gives a view's image by name for the worst-views page; with
    ``page_images`` each page is also written as ``report_page_N.png`` (the README's figures)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = report_data(a, dets)
    numbers = report_numbers(d)
    if hand_eye is not None:
        numbers["hand_eye"] = hand_eye_numbers(hand_eye)
    (out / "report.json").write_text(json.dumps(numbers, indent=1, default=float))

    page_no = 0

    def save(fig: Any, pdf: Any) -> None:
        nonlocal page_no
        page_no += 1
        _tidy(fig)
        pdf.savefig(fig)
        if page_images:
            fig.savefig(out / f"report_page_{page_no}.png", dpi=60)
        plt.close(fig)

    with PdfPages(out / "report.pdf") as pdf:
        fig, ax = plt.subplots(1, 2, figsize=(16, 9), gridspec_kw={"width_ratios": [1.25, 1]})
        _text(ax[0], ["pascal_calib_ros calibration report", "", *summary_lines(d)])
        panel_regional(ax[1], d)
        save(fig, pdf)
        fig, ax = plt.subplots(1, 2, figsize=(16, 7))
        panel_hulls(ax[0], d)
        panel_views_per_region(ax[1], fig, d)
        save(fig, pdf)
        fig, ax = plt.subplots(1, 2, figsize=(16, 7))
        panel_magnitudes(ax[0], fig, d)
        panel_directions(ax[1], d)
        save(fig, pdf)
        fig, ax = plt.subplots(2, 2, figsize=(16, 10))
        panel_regional(ax[0][0], d, labels=True)
        panel_radial(ax[0][1], d)
        panel_histogram(ax[1][0], d, numbers["residuals"]["histogram"])
        panel_per_view(ax[1][1], d)
        save(fig, pdf)
        worst = worst_views(d)
        fig, ax = plt.subplots(1, max(len(worst), 1), figsize=(18, 6), squeeze=False)
        for a, k in zip(ax[0], worst, strict=False):
            name = d.used_names[k] if k < len(d.used_names) else ""
            panel_worst(a, d, k, images(name) if images is not None and name else None)
        save(fig, pdf)
        for panel in (panel_distortion, panel_projection):
            fig, a1 = plt.subplots(1, 1, figsize=(12, 8))
            panel(a1, fig, d)
            save(fig, pdf)
        if hand_eye is not None:
            fig, ax = plt.subplots(1, 2, figsize=(16, 8), gridspec_kw={"width_ratios": [1.1, 1]})
            lines = [w for line in hand_eye_summary(hand_eye).splitlines()
                     for w in textwrap.wrap(line, 110, subsequent_indent="      ") or [""]]
            _text(ax[0], ["hand-eye calibration", "", *lines], fontsize=7)
            panel_hand_eye(ax[1], hand_eye)
            save(fig, pdf)

    fig, ax = plt.subplots(2, 3, figsize=(20, 11))
    panel_directions(ax[0][0], d)
    panel_views_per_region(ax[0][1], fig, d)
    panel_regional(ax[0][2], d)
    panel_distortion(ax[1][0], fig, d)
    panel_projection(ax[1][1], fig, d)
    _text(ax[1][2], summary_lines(d, 62), fontsize=8)
    _tidy(fig)
    fig.savefig(out / "report.png", dpi=80)
    plt.close(fig)
    return ReportFiles(out / "report.png", out / "report.json", out / "report.pdf", d.bias)
