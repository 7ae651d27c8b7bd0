"""Edges along a traced contour: a feature's edge where its image is no conic (issue 36).

A wide lens (k1 -0.28 at 1280x720, f 640 px) bends a close ring's image away from any ellipse by
several pixels near the image's corners. Profiles laid along a fitted ellipse's normals then cross
the bent edge obliquely or miss it (edge points 4 px off the truth were accepted). Here the
profiles follow the traced outline itself:

1. The contour (the threshold mask's boundary, whole pixels) is resampled by arc length and
   smoothed by a periodic Gaussian of ``SMOOTH`` px of arc (pixel quantisation of +-0.7 px falls
   to about 0.1 px; the lens bends over tens of pixels, so the shape is kept); its unit normals
   n = (t_y, -t_x) (t the tangent), turned to point away from the enclosed region.
2. Along each normal the blurred step a + b s + c Phi((s - s0) / w) is fitted
   (:func:`.edges.fit_step_profiles`, the same model as :func:`.edges.refine_edge`); profiles with
   low contrast, a wide step, an edge at the window's end or a contrast of the wrong sign are
   dropped. The point is p + (s0 + w^2 kappa / 2) n, kappa the smoothed contour's curvature
   (positive where convex seen from outside): a blurred curved edge's half level lies on its
   concave side by w^2 kappa / 2 (PAPER.md, last section).
3. A second pass follows the first pass's points (smoothed alike), so the normals are the
   edge's own; points whose offset jumps from the running median of their 9 neighbours' by more
   than ``max(6 MAD, 0.3 px)`` are dropped (clutter touching the edge).

:func:`distance_to_curve` gives each point's distance to a closed polyline: the detector drops
edge points of the ellipse path that lie far from the traced edge (:mod:`.target_detector`).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, median_filter
from scipy.spatial import cKDTree

from ..geometry import ConicFitError, fit_conic, sampson_distance
from .detection import DetectionRefusal
from .edges import EdgeError, EdgeFit, fit_step_profiles, sample_profiles

# px: an edge point of the ellipse path farther than this from the edge traced along the contour is
# not on the edge (issue 36: profiles along a fitted ellipse's normals crossing an edge the lens
# bends gave points 4 px off the truth; on ordinary views the two agree within 0.4 px)
TRACED_TOLERANCE = 1.0
SMOOTH = 3.0  # px of arc: the Gaussian smoothing of a traced contour before its normals are taken


def resample_closed(pts: np.ndarray, spacing: float) -> np.ndarray:
    """Points every ``spacing`` px of arc (at least 24) along the closed polyline ``pts`` (N, 2),
    by linear interpolation of x and y against the cumulative chord length."""
    p = np.asarray(pts, float)
    closed = np.vstack([p, p[:1]])
    arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(closed, axis=0).T))]
    n = max(24, round(float(arc[-1]) / spacing))
    s = np.linspace(0.0, arc[-1], n, endpoint=False)
    return np.stack([np.interp(s, arc, closed[:, 0]), np.interp(s, arc, closed[:, 1])], 1)


def smooth_closed(pts: np.ndarray, spacing: float, sigma: float = SMOOTH
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed curve ``pts`` resampled every ``spacing`` px and smoothed by a periodic Gaussian
    of ``sigma`` px of arc; returns the points, the outward unit normals (away from the enclosed
    region: the side the signed area's orientation says) and the curvature kappa = (x'y'' -
    y'x'') / |p'|^3, signed positive where the curve is convex seen from outside."""
    p = resample_closed(pts, spacing)
    q = gaussian_filter1d(p, sigma / spacing, axis=0, mode="wrap")
    d1 = (np.roll(q, -1, 0) - np.roll(q, 1, 0)) / 2
    d2 = np.roll(q, -1, 0) - 2 * q + np.roll(q, 1, 0)
    speed = np.hypot(d1[:, 0], d1[:, 1])
    kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(speed, 1e-12) ** 3
    normals = np.c_[d1[:, 1], -d1[:, 0]] / np.maximum(speed, 1e-12)[:, None]
    # shoelace: area > 0 for a counter-clockwise curve (x right, y down: clockwise on screen)
    area = 0.5 * float(np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]))
    orient = 1.0 if area > 0 else -1.0
    return q, normals * orient, kappa * orient


def distance_to_curve(points: np.ndarray, curve: np.ndarray, neighbours: int = 6) -> np.ndarray:
    """Each point's distance (px) to the closed polyline ``curve`` (M, 2): the least distance to
    the segments at the ``neighbours`` nearest vertices (both segments at each)."""
    a = np.asarray(curve, float)
    b = np.roll(a, -1, 0)
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d) + 1e-12
    k = min(neighbours, len(a))
    _, idx = cKDTree(a).query(points, k=k)
    idx = idx.reshape(len(points), k)
    best = np.full(len(points), np.inf)
    for j in range(k):
        for shift in (0, -1):
            i = (idx[:, j] + shift) % len(a)
            u = np.clip(np.einsum("ij,ij->i", points - a[i], d[i]) / length2[i], 0.0, 1.0)
            best = np.minimum(best, np.hypot(*(points - a[i] - u[:, None] * d[i]).T))
    return best


def refine_along_contour(image: np.ndarray, contour: np.ndarray, spacing: float = 1.5, max_width: float = 4.0,
                         min_contrast: float = 8.0, passes: int = 2, curvature_correction: bool = True,
                         room: float = np.inf) -> EdgeFit:
    """Subpixel points of the edge along the traced closed ``contour`` (module docstring) in a
    float32 grey ``image``; ``room``: the feature's narrowest half-size (px), which bounds the
    profile window as :func:`.edges.refine_edge` does (0.45 of it). The conic of the returned
    :class:`EdgeFit` is the points' best conic (a bent edge is no conic: its ``rms`` says by how
    much). Raises :class:`EdgeError` as :func:`.edges.refine_edge` does."""
    img = image if image.dtype == np.float32 else image.astype(np.float32)
    h, w = img.shape
    curve, width_est = np.asarray(contour, float), 1.0
    fit: EdgeFit | None = None
    for _ in range(passes):
        pts, normals, kappa = smooth_closed(curve, spacing)
        hw = min(float(np.clip(3.0 * width_est + 3.0, 4.0, 25.0)), 0.45 * room)
        if not np.all((pts - hw > 1) & (pts + hw < np.array([w - 2, h - 2]))):
            raise EdgeError("edge too close to the image border", DetectionRefusal.NEAR_BORDER)
        s = np.arange(-hw, hw + 1e-9, 0.5)
        s0, wid, con, rms = fit_step_profiles(sample_profiles(img, pts, normals, s), s, w0=width_est, iterations=5)
        sign = np.sign(np.median(con))
        ok = ((np.abs(con) >= min_contrast) & (np.sign(con) == sign) & (np.abs(s0) < hw - 1.0)
              & (wid < max_width) & (rms < 0.25 * np.abs(con) + 1.0))
        if ok.sum() < max(12, 0.5 * len(pts)):
            strong = np.abs(con) >= min_contrast
            if np.any(strong) and float(np.median(wid[strong])) >= max_width:
                raise EdgeError(f"edge too blurred (width {float(np.median(wid[strong])):.1f} px >= "
                                f"{max_width:.1f} px)", DetectionRefusal.TOO_BLURRED)
            raise EdgeError(f"edge not found along {100 * (1 - ok.mean()):.0f} % of the traced outline")
        shift = s0 + (0.5 * wid**2 * kappa if curvature_correction else 0.0)
        edge = pts + shift[:, None] * normals
        # outliers: a jump of the edge's offset against its neighbours' (a running median over
        # ~13 px of arc follows the lens's bending, which spans tens of px)
        run = np.full(len(shift), np.nan)
        run[ok] = median_filter(shift[ok], size=9, mode="wrap")
        jump = np.abs(shift - run)
        mad = 1.4826 * float(np.median(np.abs(jump[ok]))) + 1e-3
        ok &= jump < max(6 * mad, 0.3)
        edge, wid, con = edge[ok], wid[ok], con[ok]
        try:
            C = fit_conic(edge)
        except ConicFitError as exc:
            raise EdgeError(f"edge points do not form a closed outline: {exc}") from None
        d = sampson_distance(C, edge)
        width_est = float(np.median(wid))
        fit = EdgeFit(edge, wid, con, C, float(np.sqrt(np.mean(d * d))), float(len(edge) / len(pts)))
        curve = edge
    assert fit is not None
    return fit


def keep_on_traced(work: np.ndarray, fit: EdgeFit, contour: np.ndarray, room: float, spacing: float = 1.5,
                   max_width: float = 4.0, curvature_correction: bool = True) -> EdgeFit:
    """``fit`` (an edge refined along an ellipse's normals, :func:`.edges.refine_edge`) without its
    points farther than :data:`TRACED_TOLERANCE` from the edge refined along the traced
    ``contour`` (:func:`refine_along_contour`, ``room`` and the rest passed on); ``fit`` itself,
    unchanged, when no point is (or the traced edge cannot be refined). Where most points are
    off, the ellipse is no model of the edge: the traced edge is returned. The conic and its rms
    are refitted to the points kept."""
    try:
        traced = refine_along_contour(work, contour, spacing=spacing, max_width=max_width,
                                      curvature_correction=curvature_correction, room=room)
    except EdgeError:
        return fit
    keep = distance_to_curve(fit.points, traced.points) <= TRACED_TOLERANCE
    if keep.all():
        return fit
    if keep.mean() < 0.5:
        return traced
    pts = fit.points[keep]
    C = fit_conic(pts)
    d = sampson_distance(C, pts)
    return EdgeFit(pts, fit.width[keep], fit.contrast[keep], C, float(np.sqrt(np.mean(d * d))),
                   fit.kept_fraction * float(keep.mean()))
