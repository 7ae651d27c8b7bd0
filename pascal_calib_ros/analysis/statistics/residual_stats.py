"""Residual statistics as mrcal shows them, for circle edges and checkerboard corners.

An edge residual r (px) is measured along the outward normal n of the fitted contour, so its
vector is r n; a corner residual is a 2-vector. Both are *observed minus predicted*. The numbers:

- regional: the image cut into a grid of cells (8 x 6 for a 4:3 image); per cell the count, the
  mean residual vector, its spread (RMS about the mean) and the chi-square (2 dof) of the mean
  against its noise, mean^T (S / N_eff)^-1 mean, with S the vectors' sample covariance and
  N_eff = sum 1/kappa the effective number of independent samples (kappa: the correlation factor
  of neighbouring points along an edge, :func:`uncertainty.correlation_factors`). mrcal's
  ``show-residuals --regional``.
- radial: the component of the vectors along the direction away from the principal point, mean
  per ring of image radius, with its standard error sqrt(kappa var / N).
- model bias: detected when some cell's or radius ring's mean differs from zero by more than its
  noise at a family-wise false-alarm probability :data:`ALPHA` (Bonferroni over cells and rings)
  *and* by more than a floor in pixels (:data:`REGIONAL_FLOOR_PX`, :data:`RADIAL_FLOOR_PX`): with
  hundreds of thousands of edge points a bias of a thousandth of a pixel is statistically real and
  matters to no one. A lens model that does not fit the lens, or a sheet that is not flat, leaves
  such a pattern; an exact model leaves noise.

Reference: Kogan, mrcal documentation, "Interpreting the results" (residuals, regional, directions).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2, norm

from ...geometry import ImageSize

ALPHA = 1e-3  # family-wise probability of a false alarm on pure noise
REGIONAL_FLOOR_PX = 0.02  # a regional mean below this is not called a bias, however significant
RADIAL_FLOOR_PX = 0.008
MIN_EFFECTIVE = 20.0  # cells / rings with fewer effective samples are shown, not tested
GRID_COLS = 8
RADIAL_BINS = 10


@dataclass
class ResidualSamples:
    """Every residual of a calibration as a 2-vector at its pixel."""

    points: np.ndarray  # (N, 2) observed pixels
    vectors: np.ndarray  # (N, 2) observed minus predicted, px
    view: np.ndarray  # (N,) index of the used view
    kappa: np.ndarray  # (N,) correlation factor of the sample's kind (edge or corner)
    is_corner: np.ndarray  # (N,) bool


def contour_normals(points: np.ndarray, circle_ids: np.ndarray) -> np.ndarray:
    """Outward unit normals (N, 2) of edge points sampled in order along each circle's closed
    contour (consecutive points of one circle id): the tangent from the two neighbours, turned
    a quarter and pointed away from the contour's centroid."""
    n = np.zeros_like(points, dtype=float)
    cut = np.flatnonzero(np.diff(circle_ids)) + 1
    for sl in np.split(np.arange(len(points)), cut):
        p = points[sl]
        away = p - p.mean(0)
        if len(p) >= 5:
            t = np.roll(p, -1, 0) - np.roll(p, 1, 0)
            nn = np.stack([t[:, 1], -t[:, 0]], 1)
            nn *= np.sign(np.sum(nn * away, 1) + 1e-300)[:, None]
        else:
            nn = away
        n[sl] = nn / np.maximum(np.linalg.norm(nn, axis=1, keepdims=True), 1e-12)
    return n


def residual_samples(edge_points: list[np.ndarray], edge_residuals: list[np.ndarray],
                     edge_circles: list[np.ndarray], corner_points: list[np.ndarray] | None = None,
                     corner_residuals: list[np.ndarray] | None = None,
                     kappa: tuple[float, float] = (1.0, 1.0)) -> ResidualSamples:
    """Edge residuals as vectors r n (:func:`contour_normals`) and corner residuals (observed minus
    predicted), per used view, with the correlation factors (edges, corners)."""
    pts, vec, view, kap, corner = [], [], [], [], []
    for v, (p, r, c) in enumerate(zip(edge_points, edge_residuals, edge_circles, strict=True)):
        if len(p) == 0:
            continue
        pts.append(p)
        vec.append(np.asarray(r)[:, None] * contour_normals(p, np.asarray(c)))
        view.append(np.full(len(p), v))
        kap.append(np.full(len(p), kappa[0]))
        corner.append(np.zeros(len(p), bool))
    corner_points, corner_residuals = corner_points or [], corner_residuals or []
    if len(corner_points) != len(corner_residuals):  # corners whose residuals are not known
        corner_points = corner_residuals = []
    for v, (p, r) in enumerate(zip(corner_points, corner_residuals, strict=True)):
        if len(p) == 0 or len(r) != len(p):
            continue
        pts.append(p)
        vec.append(r)
        view.append(np.full(len(p), v))
        kap.append(np.full(len(p), kappa[1]))
        corner.append(np.ones(len(p), bool))
    if not pts:
        z = np.zeros((0, 2))
        return ResidualSamples(z, z, np.zeros(0, int), np.zeros(0), np.zeros(0, bool))
    return ResidualSamples(np.concatenate(pts), np.concatenate(vec), np.concatenate(view), np.concatenate(kap),
                           np.concatenate(corner))


def region_grid(size: ImageSize, cols: int = GRID_COLS) -> tuple[int, int]:
    """(rows, cols) of square-ish regions: ``cols`` across, as many rows as the aspect gives."""
    width, height = size
    return max(1, round(cols * height / width)), cols


def _cells(points: np.ndarray, size: ImageSize, grid: tuple[int, int]) -> np.ndarray:
    width, height = size
    rows, cols = grid
    i = np.clip((points[:, 1] * rows / height).astype(int), 0, rows - 1)
    j = np.clip((points[:, 0] * cols / width).astype(int), 0, cols - 1)
    return i * cols + j


@dataclass
class Regional:
    """Per region of a rows x cols grid (row-major): count, effective count, mean vector (px),
    spread (px), chi-square of the mean and its Bonferroni-free p-value."""

    grid: tuple[int, int]
    count: np.ndarray
    effective: np.ndarray
    mean: np.ndarray  # (cells, 2)
    spread: np.ndarray
    chi2: np.ndarray

    def as_json(self) -> dict[str, Any]:
        rows, cols = self.grid
        shape = (rows, cols)
        return {"grid": [rows, cols],
                "count": self.count.reshape(shape).tolist(),
                "mean_px": np.round(self.mean.reshape(rows, cols, 2), 5).tolist(),
                "spread_px": np.round(self.spread.reshape(shape), 5).tolist(),
                "chi2": np.round(self.chi2.reshape(shape), 3).tolist()}


def regional(s: ResidualSamples, size: ImageSize, grid: tuple[int, int] | None = None) -> Regional:
    """mrcal's regional residuals with a noise test per region (see the module docstring)."""
    grid = grid or region_grid(size)
    n_cells = grid[0] * grid[1]
    cell = _cells(s.points, size, grid)
    count = np.bincount(cell, minlength=n_cells)
    eff = np.bincount(cell, 1.0 / np.maximum(s.kappa, 1.0), minlength=n_cells)
    mean = np.zeros((n_cells, 2))
    spread = np.zeros(n_cells)
    stat = np.zeros(n_cells)
    for k in np.flatnonzero(count):
        v = s.vectors[cell == k]
        m = v.mean(0)
        mean[k] = m
        d = v - m
        spread[k] = float(np.sqrt(np.mean(np.sum(d * d, 1))))
        if count[k] >= 3:
            S = d.T @ d / (len(v) - 1)
            S += np.eye(2) * (1e-9 + 1e-6 * np.trace(S))
            stat[k] = float(m @ np.linalg.solve(S / eff[k], m))
    return Regional(grid, count, eff, mean, spread, stat)


@dataclass
class Radial:
    """Mean residual component away from the principal point per ring of image radius."""

    edges_px: np.ndarray  # (bins + 1,) ring radii
    count: np.ndarray
    effective: np.ndarray
    mean: np.ndarray  # px, positive: observed farther from the centre than predicted
    stderr: np.ndarray


def radial(s: ResidualSamples, center: tuple[float, float], bins: int = RADIAL_BINS) -> Radial:
    """Radial residual profile about ``center`` (the principal point)."""
    d = s.points - np.asarray(center, float)
    rad = np.hypot(d[:, 0], d[:, 1])
    comp = np.sum(s.vectors * d, 1) / np.maximum(rad, 1e-9)
    edges = np.linspace(0.0, float(rad.max()) * (1 + 1e-9) if len(rad) else 1.0, bins + 1)
    b = np.clip(np.searchsorted(edges, rad, side="right") - 1, 0, bins - 1)
    count = np.bincount(b, minlength=bins)
    eff = np.bincount(b, 1.0 / np.maximum(s.kappa, 1.0), minlength=bins)
    total = np.bincount(b, comp, minlength=bins)
    mean = np.divide(total, count, out=np.zeros(bins), where=count > 0)
    sq = np.bincount(b, comp * comp, minlength=bins)
    var = np.divide(sq - count * mean**2, np.maximum(count - 1, 1), out=np.zeros(bins), where=count > 1)
    stderr = np.sqrt(np.divide(np.maximum(var, 0), eff, out=np.full(bins, np.inf), where=eff > 0))
    return Radial(edges, count, eff, mean, stderr)


@dataclass
class ModelBias:
    detected: bool
    radial_px: list[float]  # mean radial residual per ring (NaN where untested)
    max_regional_px: float  # largest tested regional mean
    max_regional_at: tuple[float, float]  # its cell centre (px)
    regional_significant: int  # cells beyond both the noise and the floor
    radial_significant: int
    hint: str
    biased_regions: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # per region: beyond both

    def as_json(self) -> dict[str, Any]:
        return {"detected": self.detected, "radial_px": [round(x, 5) for x in self.radial_px],
                "max_regional_px": round(self.max_regional_px, 5),
                "max_regional_at_px": [round(x, 1) for x in self.max_regional_at],
                "regions_biased": self.regional_significant, "radius_rings_biased": self.radial_significant,
                "test": f"family-wise false-alarm probability {ALPHA:g} (Bonferroni); floors "
                        f"{REGIONAL_FLOOR_PX} px regional, {RADIAL_FLOOR_PX} px radial; noise from the "
                        "effective sample size (edge correlation)",
                "hint": self.hint, "biased_regions": np.asarray(self.biased_regions, bool).tolist()}


def model_bias(reg: Regional, rad: Radial, size: ImageSize, model: str) -> ModelBias:
    """The verdict: a systematic residual pattern beyond noise and floor (module docstring), with
    what to try in words."""
    width, height = size
    cells = reg.effective >= MIN_EFFECTIVE
    rings = rad.effective >= MIN_EFFECTIVE
    n_tests = max(int(cells.sum() + rings.sum()), 1)
    chi_lim = float(chi2.isf(ALPHA / n_tests, 2))
    z_lim = float(norm.isf(ALPHA / n_tests / 2))
    mag = np.linalg.norm(reg.mean, axis=1)
    bad_cells = cells & (reg.chi2 > chi_lim) & (mag >= REGIONAL_FLOOR_PX)
    z = np.divide(np.abs(rad.mean), rad.stderr, out=np.zeros_like(rad.mean), where=rad.stderr > 0)
    bad_rings = rings & (z > z_lim) & (np.abs(rad.mean) >= RADIAL_FLOOR_PX)
    tested_mag = np.where(cells, mag, 0.0)
    k = int(np.argmax(np.where(bad_cells, mag, 0.0) if bad_cells.any() else tested_mag)) if len(mag) else 0
    rows, cols = reg.grid
    at = ((k % cols + 0.5) * width / cols, (k // cols + 0.5) * height / rows)
    detected = bool(bad_cells.any() or bad_rings.any())
    radial_px = [float(m) if ok else float("nan") for m, ok in zip(rad.mean, rings, strict=True)]
    hint = ""
    if detected:
        richer = {"plumb_bob": "--distortion rational_polynomial (node: distortion_model rational_polynomial)",
                  "rational_polynomial": "--distortion equidistant if the lens is a fisheye",
                  "equidistant": "--distortion rational_polynomial if the lens is not a fisheye"}.get(model, "")
        where = []
        if bad_rings.any():
            rr = [m for m, b in zip(rad.mean, bad_rings, strict=True) if b]
            where.append(f"a radial pattern (mean radial residual {min(rr):+.3f} to {max(rr):+.3f} px across the "
                         "image radius)")
        if bad_cells.any():
            where.append(f"{int(bad_cells.sum())} image region(s) with a mean residual beyond the noise (up to "
                         f"{float(mag[bad_cells].max()):.3f} px near ({at[0]:.0f}, {at[1]:.0f}))")
        hint = (f"the residuals are not noise: {' and '.join(where)}. The {model} model may not describe this "
                f"lens{': try ' + richer if richer else ''}; or the sheet may not be flat: try --target-shape; if "
                f"neither removes it, some features are measured with a bias (the worst circles are listed)")
    return ModelBias(detected, radial_px, float(tested_mag.max()) if len(tested_mag) else 0.0, at,
                     int(bad_cells.sum()), int(bad_rings.sum()), hint, bad_cells)


def views_per_region(points_per_view: list[np.ndarray], size: ImageSize,
                     grid: tuple[int, int] | None = None) -> np.ndarray:
    """(rows, cols) counts: how many views have a feature point in each region."""
    grid = grid or region_grid(size)
    out = np.zeros(grid[0] * grid[1], int)
    for p in points_per_view:
        p = np.asarray(p, float).reshape(-1, 2)
        if len(p):
            out[np.unique(_cells(p, size, grid))] += 1
    return out.reshape(grid)
