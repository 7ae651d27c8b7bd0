"""Subpixel edge points of an elliptical edge, by fitting a blurred-step model to intensity
profiles along the normals of a predicted conic.

Along the normal n at a point p of the predicted curve, the profile I(s) = image(p + s n) is
fitted by I(s) = a + b s + c Phi((s - s0) / w) (Gaussian-blurred step on a linear ramp; Phi the
normal CDF), vectorised Levenberg-Marquardt over all profiles at once. The edge is p + s0 n. A
blurred *curved* edge's mid-level lies on the concave side by w^2 kappa / 2 (kappa the curvature;
for a disc of radius r blurred by sigma the half-level is at r - sigma^2 / (2 r)), so the point is
moved by w^2 kappa / 2 towards the convex side (PAPER.md, last section).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import PascalCalibError
from ..geometry import (
    ConicFitError,
    Ellipse,
    conic_curvature,
    conic_normals,
    ellipse_perimeter,
    ellipses_from_conics,
    fit_conic,
    fit_conics_algebraic,
    group_medians,
    ray_conic_nearest,
    sampson_distance,
    sampson_distances,
)
from .detection import DetectionRefusal

# a band's other edge within this many blur widths beyond a profile's window is fitted with it
# (fit_band_profiles): ring_grid_a4 at 800x600, mean fx error of 4 sessions -0.0051 % at 3.5,
# -0.0027 % at 5, -0.0024 % with every profile; 5 keeps large rings (5 MP) at the step fit's cost
BAND_REACH = 5.0
# px: the smallest profile half-window of a curve near the image border (refine_edges_batch); the
# step fit needs its two plateaus, about two blur widths either side of the edge
MIN_HALF_WINDOW = 5.0


@dataclass(frozen=True)
class EdgeFit:
    points: np.ndarray  # (N, 2) subpixel edge points, pixels
    width: np.ndarray  # (N,) fitted blur sigma of each profile, px
    contrast: np.ndarray  # (N,) step height c (signed: > 0 dark-to-bright outwards)
    conic: np.ndarray  # conic fitted to the points
    rms: float  # RMS geometric (Sampson) distance of the points to ``conic``, px
    kept_fraction: float  # profiles that gave a valid edge / profiles sampled


class EdgeError(PascalCalibError):
    """No reliable edge along this curve (blurred, occluded, low contrast); ``kind`` says which."""

    def __init__(self, message: str, kind: DetectionRefusal = DetectionRefusal.EDGE_NOT_FOUND) -> None:
        super().__init__(message)
        self.kind = kind


def sample_profiles(image: np.ndarray, pts: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` at pts + s * normals for each s in offsets: (N, M) float32."""
    mx = (pts[:, 0:1] + offsets[None, :] * normals[:, 0:1]).astype(np.float32)
    my = (pts[:, 1:2] + offsets[None, :] * normals[:, 1:2]).astype(np.float32)
    return cv2.remap(image, mx, my, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _rows64(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``a`` broadcast to ``shape`` as a C-contiguous, writeable float64 array: the one argument
    type the compiled kernels are built for (numba compiles one version per type; a read-only
    view, as ``np.broadcast_to`` gives, would be another)."""
    return np.require(np.broadcast_to(np.asarray(a, np.float64), shape), np.float64, ["C", "W"])


def fit_step_profiles(prof: np.ndarray, s: np.ndarray, w0: float = 1.0, iterations: int = 8
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fit a + b s + c Phi((s - s0)/w) to each row of ``prof`` (n, m) sampled at offsets ``s``
    (m,) or (n, m), by Levenberg-Marquardt (``iterations`` steps; damping x0.2 after a step that
    lowers the cost, x10 and the step refused otherwise; w kept in [0.15, 50] px).

    Starts from the plateaus (first and last sixth of the profile) and the moments of the
    baseline-removed derivative (centroid -> s0, spread -> w, ``w0`` where they are undefined).
    Returns s0, w, c and the RMS residual of each profile. Compiled:
    :func:`.edge_kernels.fit_step_rows` (numba, compiled on the first call, then cached on disk)."""
    from . import edge_kernels

    n, m = prof.shape
    out = edge_kernels.fit_step_rows(_rows64(prof, (n, m)), _rows64(s, (n, m)), float(w0), int(iterations))
    return out[:, 0], out[:, 1], out[:, 2], out[:, 3]


def fit_band_profiles(prof: np.ndarray, S: np.ndarray, lo0: np.ndarray, hi0: np.ndarray,
                      w0: float | np.ndarray = 1.0, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Fit a + b s - c [Phi((s - lo)/w_lo) - Phi((s - hi)/w_hi)] (a band of contrast c between two
    blurred edges lo < hi, on a linear ramp) to each row of ``prof`` sampled at the rows of ``S``;
    Levenberg-Marquardt as :func:`fit_step_profiles`, from the edges ``lo0``, ``hi0`` and blur
    ``w0`` (per row or one), the level from the mean of both ends (an eighth of the profile
    each), the contrast from the darkest sample.

    A thin band's two edges share their blurred tails: a single step fitted to one of them is
    pulled towards the other (ring_grid_a4 at 800x600: bands of 3-6 px, by up to 0.3 px, more where
    foreshortening narrows the band, hence the elliptical residual pattern of each ring). Returns
    the parameters (n, 7) [a, b, c, lo, w_lo, hi, w_hi] and each profile's RMS residual.
    Compiled: :func:`.edge_kernels.fit_band_rows`."""
    from . import edge_kernels

    n, m = prof.shape
    start = np.stack([np.broadcast_to(np.asarray(v, np.float64), (n,)) for v in (lo0, hi0, w0)], 1)
    out = edge_kernels.fit_band_rows(_rows64(prof, (n, m)), _rows64(S, (n, m)), start, int(iterations))
    return out[:, :7], out[:, 7]


def _fit_bands(img: np.ndarray, P: np.ndarray, N: np.ndarray, hw: np.ndarray, C_other: np.ndarray,
               rows: np.ndarray, m: int, step: tuple[np.ndarray, ...]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The profiles ``rows`` (points P, normals N, half-windows hw) refitted across the band to
    the partner edge ``C_other`` (one conic per row): their s0, width, contrast (sign as the step
    fit's) and RMS replace ``step``'s where the normal meets the partner close enough for its
    blurred tail (BAND_REACH blur widths) to reach the window (elsewhere, on a strongly tilted ring, the
    normal passes beside the inner edge, and on a large ring the partner is far: the step fit
    stays); the returned mask is False where the fit lost the band. The fit starts from the step
    fit's edge and width."""
    s0, wid, con, rms = (a.copy() for a in step)
    ok = np.ones(len(s0), bool)
    s_meet = ray_conic_nearest(C_other, P[rows], N[rows])
    w_step = np.clip(wid[rows], 0.5, 3.0)
    near = (np.isfinite(s_meet) & (np.abs(s_meet) > 0.5) & (np.abs(s_meet) < hw[rows] + BAND_REACH * w_step)
            & (np.abs(s0[rows]) < hw[rows]))
    rows, s_other, w_step = rows[near], s_meet[near], w_step[near]
    if len(rows) == 0:
        return s0, wid, con, rms, ok
    Pr, Nr, h = P[rows], N[rows], hw[rows]
    own0 = s0[rows]
    lo0, hi0 = np.where(s_other < 0, s_other, own0), np.where(s_other < 0, own0, s_other)
    S = (lo0 - h)[:, None] + np.linspace(0.0, 1.0, m)[None, :] * (hi0 - lo0 + 2 * h)[:, None]
    mx = (Pr[:, 0:1] + S * Nr[:, 0:1]).astype(np.float32)
    my = (Pr[:, 1:2] + S * Nr[:, 1:2]).astype(np.float32)
    prof = cv2.remap(img, mx, my, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    p, r = fit_band_profiles(prof, S, lo0, hi0, w_step, iterations=4)
    own_hi = s_other < 0  # the partner lies inwards: this curve's edge is the band's outer side
    s0[rows] = np.where(own_hi, p[:, 5], p[:, 3])
    wid[rows] = np.where(own_hi, p[:, 6], p[:, 4])
    con[rows] = np.where(own_hi, p[:, 2], -p[:, 2])  # > 0: dark-to-bright outwards, as the step fit
    rms[rows] = r
    other = np.where(own_hi, p[:, 3], p[:, 5])
    ok[rows] = (p[:, 5] - p[:, 3] > 0.3) & (np.abs(other - s_other) < h) & np.all(np.isfinite(p), 1)
    return s0, wid, con, rms, ok


def turns_back(prof: np.ndarray, S: np.ndarray, start: np.ndarray, reach: np.ndarray, threshold: np.ndarray
               ) -> np.ndarray:
    """Rows of ``prof`` (sampled at increasing offsets ``S``) in which the level, walking from
    ``start`` to ``reach`` (per row), falls back below the highest level seen so far by more than
    ``threshold``: another edge begins there. Pass -prof for a level that should not rise."""
    walk = (S >= start[:, None]) & (S <= reach[:, None])
    run = np.maximum.accumulate(np.where(walk, prof, -np.inf), axis=1)
    return np.any(walk & (prof < run - threshold[:, None]), axis=1)


def refine_edge(image: np.ndarray, conic: np.ndarray, spacing: float = 1.0, half_window: float | None = None,
                max_width: float = 6.0, min_contrast: float = 8.0, passes: int = 2,
                curvature_correction: bool = True, max_profiles: int = 720, second_edge: bool = False) -> EdgeFit:
    """Subpixel points of the edge near ``conic`` in a float32 grey ``image``.

    Samples one profile per ``spacing`` px of arc (at most ``max_profiles``: the refinement uses
    at most 700 points of a view, the conic fit gains little beyond) along the predicted ellipse,
    fits the blurred
    step, rejects profiles with low contrast, too wide a step, an edge outside the window or an
    inconsistent sign, refits the conic, and repeats ``passes`` times. ``second_edge``: also drops
    the profiles with another edge on the bright side (:func:`_second_edge`; off by default: on the
    fisheye renders of test_wide_single_ring it moved the model error from below 0.5 px to 0.62 px,
    not understood yet). Raises :class:`EdgeError`."""
    img = image if image.dtype == np.float32 else image.astype(np.float32)
    h, w = img.shape
    C = conic
    width_est = 1.0
    fit: EdgeFit | None = None
    for k in range(passes):
        try:
            e = Ellipse.from_conic(C)
        except ConicFitError as exc:
            raise EdgeError(str(exc)) from None
        # early passes only re-centre the curve: sample them sparsely
        n = int(np.clip(e.perimeter / (spacing * (4 if k < passes - 1 else 1)), 24, max_profiles))
        pts = e.sample(n)
        normals = conic_normals(C, pts)
        hw = half_window if half_window is not None else float(np.clip(3.0 * width_est + 3.0, 4.0, 25.0))
        hw = min(hw, 0.45 * e.b) if e.b > 4 else hw
        s = np.arange(-hw, hw + 1e-9, 0.5)
        inside = ((pts[:, 0] - hw > 1) & (pts[:, 0] + hw < w - 2) & (pts[:, 1] - hw > 1) & (pts[:, 1] + hw < h - 2))
        if inside.mean() < 0.999:
            raise EdgeError("edge too close to the image border", DetectionRefusal.NEAR_BORDER)
        more = 0.5 * np.arange(1, int(2 * hw) + 1)  # the window and as far again beyond each end
        s_ext = np.r_[s[0] - more[::-1], s, s[-1] + more]
        prof_ext = sample_profiles(img, pts, normals, s_ext)
        prof = prof_ext[:, len(more):len(more) + len(s)]
        s0, wid, con, rms = fit_step_profiles(prof, s, w0=width_est, iterations=5)
        sign = np.sign(np.median(con))
        ok = ((np.abs(con) >= min_contrast) & (np.sign(con) == sign) & (np.abs(s0) < hw - 1.0)
              & (wid < max_width) & (rms < 0.25 * np.abs(con) + 1.0))
        beyond = _second_edge(prof_ext, s_ext, s0, wid, con, rms, hw) & ok if second_edge else np.zeros(n, bool)
        ok &= ~beyond
        if ok.sum() < max(12, 0.5 * n):
            if beyond.sum() >= 0.25 * n:
                raise EdgeError(f"another edge (the sheet's?) beside the edge along {100 * beyond.mean():.0f} % "
                                "of the curve: the paper around the feature is too thin in view")
            med = float(np.median(wid[np.abs(con) >= min_contrast])) if np.any(np.abs(con) >= min_contrast) else np.inf
            if med >= max_width:
                raise EdgeError(f"edge too blurred (width {med:.1f} px >= {max_width:.1f} px)",
                                DetectionRefusal.TOO_BLURRED)
            raise EdgeError(f"edge not found along {100 * (1 - ok.mean()):.0f} % of the curve "
                            "(occluded, low contrast or not an ellipse)")
        shift = s0.copy()
        if curvature_correction:
            kappa = conic_curvature(C, pts)
            shift = shift + 0.5 * wid**2 * kappa
        edge_pts = pts + shift[:, None] * normals
        edge_pts, wid, con = edge_pts[ok], wid[ok], con[ok]
        try:
            C_new = fit_conic(edge_pts)
        except ConicFitError as exc:
            raise EdgeError(f"edge points do not form an ellipse: {exc}") from None
        d = sampson_distance(C_new, edge_pts)
        # drop gross outliers (occlusion, clutter touching the edge) and refit once
        mad = 1.4826 * np.median(np.abs(d - np.median(d))) + 1e-3
        good = np.abs(d) < max(6 * mad, 0.3)
        if good.mean() < 0.999:
            edge_pts, wid, con = edge_pts[good], wid[good], con[good]
            C_new = fit_conic(edge_pts)
            d = sampson_distance(C_new, edge_pts)
        C = C_new
        width_est = float(np.median(wid))
        fit = EdgeFit(edge_pts, wid, con, C, float(np.sqrt(np.mean(d * d))), float(len(edge_pts) / n))
    assert fit is not None
    return fit


def _second_edge(prof_ext: np.ndarray, s_ext: np.ndarray, s0: np.ndarray, wid: np.ndarray, con: np.ndarray,
                 rms: np.ndarray, hw: float) -> np.ndarray:
    """Profiles (rows of ``prof_ext``, sampled at ``s_ext``, twice the fitted window) that show a
    second edge on the edge's bright side: walking from one blur width past the fitted edge s0 to
    3 blur widths beyond the window (at most twice the half-window ``hw``), the level turns back
    (:func:`turns_back`) by more than 5 % of the median contrast or 4 x the median fit residual.
    The bright side is the paper around a printed feature: a level that falls there is the sheet's
    own edge (or anything beyond it), whose blurred step pulls the fitted edge towards it (issue
    36: ring_a4 through a wide lens, outer edge points up to 4.5 px off where the sheet's edge
    came within the window); as :func:`_edge_beyond` does for grid elements."""
    up = np.sign(con) >= 0  # the level rises along +s: the bright side is ahead
    q = np.where(up[:, None], prof_ext, prof_ext[:, ::-1])  # rows reversed where the bright side is at -s
    t = np.where(up[:, None], s_ext[None, :], -s_ext[None, ::-1])
    start = np.where(up, s0, -s0) + wid
    reach = np.minimum(hw + 3 * wid, 2 * hw)
    thr = np.full(len(s0), max(0.05 * float(np.median(np.abs(con))), 4.0 * float(np.median(rms))))
    return turns_back(q, t, start, reach, thr)


def refine_edges_batch(image: np.ndarray, conics: list[np.ndarray], half_windows: np.ndarray, spacing: float = 1.5,
                       max_width: float = 6.0, min_contrast: float = 8.0, curvature_correction: bool = True,
                       samples: int = 13, look_outside: np.ndarray | None = None, outside_reach: float = 3.0,
                       outside_cap: float = 1.0, outside_fall: float = 0.05, partners: np.ndarray | None = None
                       ) -> list[EdgeFit | None]:
    """:func:`refine_edge` for many small curves at once (grid elements): one profile sampling,
    one vectorised step fit and batched algebraic conic fits for all of them. A curve whose edge
    cannot be measured gives None.

    ``look_outside`` (one flag per curve; grids: the outer edges) drops the profiles of a curve
    that show another edge on the curve's outer side, from one blur width past the fitted edge to
    ``outside_reach`` fitted blur widths beyond the window (at most ``outside_cap`` half-windows):
    the level there turns back by more than ``outside_fall`` of the curve's median contrast
    (:func:`_edge_beyond` says why).

    ``partners`` (one index into ``conics`` per curve, -1 for none; grids: a ring's outer and inner
    edge) names the other edge of the same dark band: each profile then reaches across the band
    to the partner (where the normal meets it) and is fitted with both edges
    (:func:`fit_band_profiles`); the curve's own edge is reported."""
    img = image if image.dtype == np.float32 else image.astype(np.float32)
    out: list[EdgeFit | None] = [None] * len(conics)
    if not conics:
        return out
    C_all = np.array(conics, float)
    par, real = ellipses_from_conics(C_all)
    # a curve near the image border is measured with the window the image leaves it (the sheet
    # around an element may be cut by the border, the element is whole), down to MIN_HALF_WINDOW
    asked = np.asarray(half_windows, float)
    with np.errstate(invalid="ignore"):
        hw_all = np.minimum(asked, _window_room(par, img.shape))
        use = np.flatnonzero(real & (hw_all >= np.minimum(asked, MIN_HALF_WINDOW)))
    if len(use) == 0:
        return out
    n_u = np.clip(ellipse_perimeter(par[use, 2], par[use, 3]) / spacing, 12, 2000).astype(int)
    gid, k, P, N = _curve_normals(par, C_all, use, n_u)
    hw = hw_all[k]
    # the window, and beyond each end as far again for the outside check
    look = np.zeros(len(use), bool) if look_outside is None else np.asarray(look_outside, bool)[use]
    unit = np.linspace(-1.0, 1.0, samples)
    ext = np.linspace(-2.0, 2.0, 2 * samples - 1) if look.any() else unit
    window = slice((len(ext) - samples) // 2, (len(ext) + samples) // 2)  # unit = ext[window]
    S_ext = ext[None, :] * hw[:, None]
    mx = (P[:, 0:1] + S_ext * N[:, 0:1]).astype(np.float32)
    my = (P[:, 1:2] + S_ext * N[:, 1:2]).astype(np.float32)
    prof_ext = cv2.remap(img, mx, my, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    prof, S = prof_ext[:, window], S_ext[:, window]
    # three iterations from the moment start: more move s0 by < 0.01 px (99 % below 0.006 px; grey
    # noise moves it by 0.05 px) and did not change `pascal-calib study grids` beyond its noise
    s0, wid, con, rms = fit_step_profiles(prof, S, iterations=3)
    band_ok = np.ones(len(gid), bool)
    part = np.full(len(conics), -1) if partners is None else np.asarray(partners, int)
    rows = np.flatnonzero(part[k] >= 0)
    if len(rows):
        s0, wid, con, rms, band_ok = _fit_bands(img, P, N, hw, C_all[part[k[rows]]], rows, 2 * samples - 1,
                                                (s0, wid, con, rms))
    sign = np.sign(np.bincount(gid, np.sign(con), len(use)))  # the majority's sign = the median's
    ok = ((np.abs(con) >= min_contrast) & (np.sign(con) == sign[gid]) & (np.abs(s0) < hw - 0.25)
          & (wid < max_width) & (rms < 0.25 * np.abs(con) + 1.0) & band_ok)
    if look.any():
        fits = _StepFits(s0=s0, wid=wid, con=con, rms=rms, sign=sign)
        beyond = _edge_beyond(prof_ext, S_ext, P - par[k, :2], N, gid=gid, fits=fits, hw=hw,
                              reach=np.minimum(hw + outside_reach * wid, (1 + outside_cap) * hw),
                              fall=outside_fall) & look[gid]
        ok &= ~beyond
    else:
        beyond = np.zeros(len(gid), bool)
    # an element needs most of its profiles; those dropped for an edge beyond them do not count
    # (a corner disc facing two borders would otherwise be lost)
    enough = np.bincount(gid, ok, len(use)) >= np.maximum(8, 0.6 * (n_u - np.bincount(gid, beyond, len(use))))
    shift = s0 + 0.5 * wid**2 * conic_curvature(C_all[k], P) if curvature_correction else s0
    keep = ok & enough[gid]
    curves = np.flatnonzero(enough)
    if len(curves) == 0:
        return out
    remap = np.full(len(use), -1)
    remap[curves] = np.arange(len(curves))
    fits_c = _fit_curves((P + shift[:, None] * N)[keep], remap[gid[keep]], wid[keep], con[keep], n_u[curves])
    for c, fit in zip(curves, fits_c, strict=True):
        out[use[c]] = fit
    return out


def _window_room(par: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The largest profile half-window of each ellipse (rows cx, cy, a, b, angle) that keeps its
    profiles inside the image, one pixel from its border: the room around its bounding box."""
    h, w = shape[:2]
    cx, cy, a, b, ang = par.T
    ext_x = np.sqrt((a * np.cos(ang)) ** 2 + (b * np.sin(ang)) ** 2)
    ext_y = np.sqrt((a * np.sin(ang)) ** 2 + (b * np.cos(ang)) ** 2)
    return np.minimum.reduce([cx - ext_x - 1, cy - ext_y - 1, w - 2 - cx - ext_x, h - 2 - cy - ext_y])


def _curve_normals(par: np.ndarray, C_all: np.ndarray, use: np.ndarray, n_u: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``n_u[i]`` points on ellipse ``use[i]``, equally spaced in the parametric angle, with the
    unit normals of its conic there (the gradient of xᵀCx). Returns (gid, k, P, N): each point's
    compact curve index, its curve's index in ``C_all``, the points (n, 2) and the normals (n, 2)."""
    cx, cy, a, b, ang = par.T
    gid = np.repeat(np.arange(len(use)), n_u)
    start = np.concatenate([[0], np.cumsum(n_u)[:-1]])
    t = 2 * np.pi * (np.arange(len(gid)) - start[gid]) / n_u[gid]
    k = use[gid]
    ex, ey = a[k] * np.cos(t), b[k] * np.sin(t)
    c_, s_ = np.cos(ang[k]), np.sin(ang[k])
    P = np.stack([cx[k] + c_ * ex - s_ * ey, cy[k] + s_ * ex + c_ * ey], 1)
    X = np.concatenate([P, np.ones((len(P), 1))], 1)
    grad = np.einsum("nj,njk->nk", X, C_all[k])[:, :2]
    return gid, k, P, grad / np.linalg.norm(grad, axis=1, keepdims=True)


@dataclass(frozen=True)
class _StepFits:
    """The step fit of every profile (offset, blur width, signed contrast, residual RMS) and the
    majority sign of the contrast of each curve."""

    s0: np.ndarray
    wid: np.ndarray
    con: np.ndarray
    rms: np.ndarray
    sign: np.ndarray


def _edge_beyond(prof_ext: np.ndarray, S_ext: np.ndarray, from_centre: np.ndarray, N: np.ndarray, *,
                 gid: np.ndarray, fits: _StepFits, hw: np.ndarray, reach: np.ndarray, fall: float) -> np.ndarray:
    """Profiles that show another edge on their curve's outer side: walking outwards from one blur
    width past the fitted edge, up to ``reach``, the level (the outside's plateau) turns back by
    more than ``fall`` of the curve's median contrast or 4 x the median fit residual (noise).

    The step model has no term for a second edge, and even its blurred tail entering the window
    pulls the fitted edge towards it. Why: the outer discs of disc_grid_a4 lie 3.5 mm (x) and 5 mm
    (y) inside the sheet's border (paper to a darker background), 0.8-1.1 half-windows from their
    edge; on renders their profiles facing the border came out 0.05 px (gamma 2.2) to 0.1 px
    (linear) further inside the true outline than the inner discs', and fx -0.03..-0.07 % (3-5
    sigma) at blur 1 px. Without those profiles fx matches renders of a sheet 20 mm wider (mean
    +0.008 % against +0.006 % over 8 sessions and noise draws; at blur 2 px -0.1..-0.3 % became
    +0.01..+0.03 %). A neighbour's edge that close is dropped alike (strongly tilted views: their
    profiles were biased the same way)."""
    o = np.where(np.einsum("ij,ij->i", from_centre, N) < 0, -1.0, 1.0)  # +1: the normal points outwards
    up = o * fits.sign[gid]  # +1: the outside is the bright side
    n_curves = len(fits.sign)
    thr = np.maximum(fall * group_medians(np.abs(fits.con), gid, n_curves)[gid], 4.0 * float(np.median(fits.rms)))
    flip = (o < 0)[:, None]  # reverse those rows: the offsets then increase outwards in all
    q = np.where(flip, prof_ext[:, ::-1], prof_ext) * up[:, None]
    t = np.where(flip, -S_ext[:, ::-1], S_ext)
    return turns_back(q, t, fits.s0 * o + fits.wid, reach, thr)


def _fit_curves(pts: np.ndarray, own: np.ndarray, wid: np.ndarray, con: np.ndarray, n_profiles: np.ndarray
                ) -> list[EdgeFit | None]:
    """Batched algebraic conic fits of the edge points ``pts`` of curve ``own`` (0..len(n_profiles)-1),
    gross outliers (clutter touching the edge: > 6 MAD, at least 0.3 px) dropped and refitted once;
    None for a curve whose fit fails or keeps fewer than 5 points."""
    n_curves = len(n_profiles)
    Cf, fit_ok = fit_conics_algebraic(pts, own, n_curves)
    d = sampson_distances(Cf, pts, own)
    med = group_medians(d, own, n_curves)
    mad = 1.4826 * group_medians(np.abs(d - med[own]), own, n_curves)
    good = np.abs(d) < np.maximum(6 * mad, 0.3)[own]
    if not good.all():
        pts, own, wid, con = pts[good], own[good], wid[good], con[good]
        Cf, ok_r = fit_conics_algebraic(pts, own, n_curves)
        fit_ok &= ok_r
        d = sampson_distances(Cf, pts, own)
    counts = np.bincount(own, minlength=n_curves)
    rms_c = np.sqrt(np.bincount(own, d * d, n_curves) / np.maximum(counts, 1))
    bounds = np.concatenate([[0], np.cumsum(counts)])
    fits: list[EdgeFit | None] = [None] * n_curves
    for j in range(n_curves):
        if fit_ok[j] and counts[j] >= 5:
            lo, hi = bounds[j], bounds[j + 1]
            fits[j] = EdgeFit(pts[lo:hi], wid[lo:hi], con[lo:hi], Cf[j], float(rms_c[j]),
                              float(counts[j] / n_profiles[j]))
    return fits
