"""Plumb-line initialisation for grid boards under strong distortion.

The closed-form solvers assume conics, i.e. no lens distortion; with k1 around -0.4 their
result is not even positive definite. On a grid the element centres lie on straight rows and
columns in an undistorted image, so a one-parameter division model (Fitzgibbon 2001)
p_u = c + (p - c) / (1 + lambda |p - c|^2), centred on the image, is chosen to make them
straightest (golden-section search on the summed squared line residuals of every row and column
of every view). The edges are undistorted with it, conics refitted, and the closed form runs on
those; lambda f^2 starts the plumb_bob k1 of the refinement.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ...detect import Detection
from ...geometry import Camera, ellipses_from_conics, fit_conics_algebraic, sampson_distances
from ...targets import Target


def _lines_of_centres(det: Detection, target: Target) -> list[np.ndarray]:
    """Image centres of the elements along each labelled row and column (>= 3 each)."""
    pos: dict[tuple[int, int], np.ndarray] = {}
    circles = target.circles
    elems = [e for e in det.edges if circles[e.circle].dark_inside and "_grid[" in circles[e.circle].feature]
    par, real = ellipses_from_conics(np.array([e.conic for e in elems]))
    for e, p, ok in zip(elems, par, real, strict=True):
        if ok:
            r, col = (int(v) for v in circles[e.circle].feature.split("[")[1].split("]")[0].split(","))
            pos[(r, col)] = p[:2]
    lines = []
    for key_axis in (0, 1):
        groups: dict[int, list[np.ndarray]] = {}
        for rc, p in pos.items():
            groups.setdefault(rc[key_axis], []).append(p)
        lines += [np.array(g) for g in groups.values() if len(g) >= 3]
    return lines


def _undistort(p: np.ndarray, lam: float, centre: np.ndarray) -> np.ndarray:
    d = p - centre
    return centre + d / (1.0 + lam * np.sum(d * d, axis=-1, keepdims=True))


class _Lines:
    """All rows and columns of all views, flattened for a vectorised straightness measure."""

    def __init__(self, lines: list[np.ndarray]):
        self.pts = np.concatenate(lines)
        self.idx = np.concatenate([np.full(len(ln), i) for i, ln in enumerate(lines)])
        self.count = np.bincount(self.idx).astype(float)


def _straightness(lines: _Lines, lam: float, centre: np.ndarray) -> float:
    """Sum over lines of the smallest eigenvalue of the scatter matrix of the undistorted points
    (the squared residual of the total-least-squares line)."""
    q = _undistort(lines.pts, lam, centre)
    n = len(lines.count)
    mean = np.stack([np.bincount(lines.idx, q[:, k], n) for k in (0, 1)], 1) / lines.count[:, None]
    d = q - mean[lines.idx]
    a = np.bincount(lines.idx, d[:, 0] * d[:, 0], n)
    b = np.bincount(lines.idx, d[:, 0] * d[:, 1], n)
    c = np.bincount(lines.idx, d[:, 1] * d[:, 1], n)
    smallest = (a + c) / 2 - np.sqrt(((a - c) / 2) ** 2 + b * b)
    return float(np.sum(np.maximum(smallest, 0.0)))


def division_parameter(dets: list[Detection], target: Target) -> float:
    """lambda (1/px^2) of the division model that makes the grid lines straightest."""
    w, h = dets[0].width, dets[0].height
    centre = np.array([w / 2, h / 2])
    line_list = [ln for d in dets for ln in _lines_of_centres(d, target)]
    if not line_list:
        return 0.0
    lines = _Lines(line_list)
    r2 = float(np.max(np.sum((lines.pts - centre) ** 2, axis=1)))
    lo, hi = -0.9 / r2, 0.5 / r2  # the model must stay invertible over the measured points
    g = (np.sqrt(5) - 1) / 2
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = _straightness(lines, a, centre), _straightness(lines, b, centre)
    for _ in range(60):
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = _straightness(lines, a, centre)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = _straightness(lines, b, centre)
    return float((lo + hi) / 2)


def undistort_detections(dets: list[Detection], lam: float) -> list[Detection]:
    """Copies of the detections with edge points undistorted by the division model and conics
    refitted (checkerboard corners likewise)."""
    out = []
    for d in dets:
        centre = np.array([d.width / 2, d.height / 2])
        edges = []
        if d.edges:
            pts = [_undistort(e.points, lam, centre) for e in d.edges]
            owner = np.repeat(np.arange(len(pts)), [len(p) for p in pts])
            conics, ok = fit_conics_algebraic(np.concatenate(pts), owner, len(pts))
            edges = [replace(e, points=p, conic=C) for e, p, C, good in zip(d.edges, pts, conics, ok, strict=True)
                     if good]
        corners = None if d.corners is None else _undistort(d.corners, lam, centre)
        out.append(replace(d, edges=edges, corners=corners))
    return out


def plumb_bob_from_division(lam: float, f: float, r_max: float, with_k2: bool = True) -> tuple[float, float]:
    """(k1, k2) of plumb_bob closest to the division model over radii 0..r_max px, for focal f:
    least squares of rho_d = rho_u (1 + k1 rho_u^2 + k2 rho_u^4) in normalised coordinates."""
    r_d = np.linspace(0.0, r_max, 200)[1:]
    r_u = r_d / (1.0 + lam * r_d * r_d)
    ok = (1.0 + lam * r_d * r_d) > 0.05
    rho_u, rho_d = r_u[ok] / f, r_d[ok] / f
    A = np.stack([rho_u**3, rho_u**5], 1) if with_k2 else rho_u[:, None] ** 3
    coef = np.linalg.lstsq(A, rho_d - rho_u, rcond=None)[0]
    return float(coef[0]), float(coef[1]) if with_k2 else 0.0


# -- fisheye (equidistant) start ---------------------------------------------------------------
# Under a fisheye, circles do not image as conics and lines do not image as lines, so the closed
# forms need undistorted edges, and the lens is unknown. The generic equidistant lens
# r = f theta, centred on the image, is the start: its one parameter f is chosen so that the
# target's straight rows (grid centres, checkerboard rows) map to great circles of the ray sphere
# (their rays are coplanar with the camera centre: the plumb-line idea on rays, which works for
# rays at and beyond 90 degrees), or, for a single ring, so that its edges are exact conics in the
# virtual pinhole image. The edges are then drawn in a virtual pinhole camera (focal f, rays
# within VIRTUAL_MAX_ANGLE) where the closed forms run unchanged.

VIRTUAL_MAX_ANGLE = np.radians(70.0)


def generic_fisheye(f: float, centre: np.ndarray) -> Camera:
    """The generic equidistant lens r = f theta (no coefficients) centred at ``centre``."""
    return Camera(np.array([[f, 0.0, centre[0]], [0.0, f, centre[1]], [0.0, 0.0, 1.0]]), np.zeros(4),
                  model="equidistant")


def equidistant_rays(p: np.ndarray, f: float, centre: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) of pixels under the generic equidistant lens r = f theta."""
    return generic_fisheye(f, centre).lens.undistort((p - centre) / f, np.zeros(4), strict=False)


def _corner_lines(det: Detection, target: Target) -> list[np.ndarray]:
    """Rows and columns of the board's corners (target order: row-major), the measured corners of
    each with at least three."""
    board = target.board
    if det.corners is None or board is None:
        return []
    cols, rows = board.inner_corners
    grid = det.corners.reshape(rows, cols, 2)
    lines = [grid[i] for i in range(rows)] + [grid[:, j] for j in range(cols)]
    lines = [ln[np.isfinite(ln[:, 0])] for ln in lines]
    return [ln for ln in lines if len(ln) >= 3]


def _ray_planarity(lines: _Lines, f: float, centre: np.ndarray) -> float:
    """Sum over lines of lambda_min / lambda_mid of the second moment of their rays: zero when
    each line's rays lie in a plane through the camera centre, scale-free (rays that crowd
    together as f grows do not make it small)."""
    rays = equidistant_rays(lines.pts, f, centre)
    n = len(lines.count)
    M = np.zeros((n, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            M[:, i, j] = M[:, j, i] = np.bincount(lines.idx, rays[:, i] * rays[:, j], n)
    w = np.linalg.eigvalsh(M)
    return float(np.sum(w[:, 0] / np.maximum(w[:, 1], 1e-300)))


def _virtual_pinhole(p: np.ndarray, f: float, centre: np.ndarray) -> np.ndarray:
    """Pixels of the virtual pinhole camera (focal f, principal point ``centre``) seeing the rays
    of the equidistant guess; NaN beyond VIRTUAL_MAX_ANGLE."""
    rays = equidistant_rays(p, f, centre)
    rays[rays[:, 2] <= np.cos(VIRTUAL_MAX_ANGLE)] = np.nan
    return Camera.from_params(f, f, float(centre[0]), float(centre[1])).project(rays)


def _conic_misfit(dets: list[Detection], f: float) -> float:
    """Mean relative algebraic misfit of the edges as conics in the virtual pinhole image (all
    edges of all views in one batched fit)."""
    pts = []
    for d in dets:
        centre = np.array([d.width / 2, d.height / 2])
        for e in d.edges:
            p = _virtual_pinhole(e.points, f, centre)
            p = p[np.all(np.isfinite(p), 1)]
            if len(p) >= 20:
                pts.append(p)
    if not pts:
        return float("inf")
    owner = np.repeat(np.arange(len(pts)), [len(p) for p in pts])
    allp = np.concatenate(pts)
    conics, ok = fit_conics_algebraic(allp, owner, len(pts))
    par, real = ellipses_from_conics(conics)
    dist = sampson_distances(conics, allp, owner)
    rms = np.sqrt(np.bincount(owner, dist * dist, len(pts)) / np.bincount(owner, minlength=len(pts)))
    size = np.sqrt(np.maximum(par[:, 2] * par[:, 3], 1e-12))
    good = ok & real
    return float(np.mean(rms[good] / size[good])) if good.any() else float("inf")


def _golden_log(fun: Callable[[float], float], lo: float, hi: float, iterations: int = 50) -> float:
    """Minimiser of ``fun`` over [lo, hi] by golden-section search on log f."""
    a_, b_ = np.log(lo), np.log(hi)
    g = (np.sqrt(5) - 1) / 2
    a, b = b_ - g * (b_ - a_), a_ + g * (b_ - a_)
    fa, fb = fun(float(np.exp(a))), fun(float(np.exp(b)))
    for _ in range(iterations):
        if fa < fb:
            b_, b, fb = b, a, fa
            a = b_ - g * (b_ - a_)
            fa = fun(float(np.exp(a)))
        else:
            a_, a, fa = a, b, fb
            b = a_ + g * (b_ - a_)
            fb = fun(float(np.exp(b)))
    return float(np.exp((a_ + b_) / 2))


def equidistant_focal(dets: list[Detection], target: Target) -> float:
    """f (px) of the generic equidistant lens r = f theta, centred on the image, that best explains
    the views: straight rows as coplanar rays (grids, checkerboards), else single-ring edges as
    conics in the virtual pinhole image (module comment above)."""
    w, h = dets[0].width, dets[0].height
    centre = np.array([w / 2, h / 2])
    line_list = [ln for d in dets for ln in (_lines_of_centres(d, target) + _corner_lines(d, target))]
    lo, hi = 0.08 * max(w, h), 4.0 * max(w, h)
    if line_list:
        lines = _Lines(line_list)
        return _golden_log(lambda f: _ray_planarity(lines, f, centre), lo, hi)
    return _golden_log(lambda f: _conic_misfit(dets, f), lo, hi, iterations=30)


def has_straight_rows(dets: list[Detection], target: Target) -> bool:
    """Whether :func:`equidistant_focal` fits f to straight rows (grid centres, checkerboard corners:
    three or more in a row in some view) rather than to single-ring conics."""
    return any(_lines_of_centres(d, target) or _corner_lines(d, target) for d in dets)


def virtual_pinhole_detections(dets: list[Detection], f: float) -> list[Detection]:
    """Copies of the detections drawn in the virtual pinhole camera of the equidistant guess:
    edge points beyond VIRTUAL_MAX_ANGLE dropped (an edge keeps at least half of its points or is
    dropped), conics refitted; a checkerboard's corners kept only if all of them are within the
    angle, a marker board's with NaN for those beyond."""
    out = []
    for d in dets:
        centre = np.array([d.width / 2, d.height / 2])
        edges = []
        pts, keep = [], []
        for e in d.edges:
            p = _virtual_pinhole(e.points, f, centre)
            good = np.all(np.isfinite(p), 1)
            if good.sum() >= max(20, len(p) // 2):
                pts.append(p[good])
                keep.append(e)
        if pts:
            owner = np.repeat(np.arange(len(pts)), [len(p) for p in pts])
            conics, ok = fit_conics_algebraic(np.concatenate(pts), owner, len(pts))
            edges = [replace(e, points=p, conic=C) for e, p, C, g in zip(keep, pts, conics, ok, strict=True) if g]
        corners = None
        if d.corners is not None:
            c = _virtual_pinhole(d.corners, f, centre)
            seen = np.isfinite(d.corners[:, 0])
            if np.all(np.isfinite(c[seen])) or d.marker_ids is not None:  # a marker board: NaN where beyond
                corners = c
        out.append(replace(d, edges=edges, corners=corners))
    return out
