"""What a view of the target at a given pose would give the refinement, synthesised at the
current estimate: its edge points on the projected circles, spaced as the detector spaces them
and thinned as the pipeline thins them, and its checkerboard corners (a :class:`ViewData`).

The detector samples one profile per ``edge_spacing`` px of arc (1.5 px for a ring, a disc or a
board's circles; twice that on a grid's elements: :mod:`..detect.grids`), at least 24 (12 on a
grid) per edge; :func:`..calibrate.pipeline.observations` then keeps at most
``max(8, min(max_points_per_edge, max_points_per_view // edges))`` evenly spread points per edge.
A synthetic view does the same with points exactly on the imaged circles (no noise: only the
Jacobian at the estimate is wanted). ``max_points`` thins further for a quick first ranking; each
point then stands for ``weight`` real ones (a quadrature of the smooth information along the
curve).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...calibrate import CalibrationOptions, ViewData
from ...detect import DEFAULT_PARAMS
from ...geometry import Camera
from ...targets import Target

# angles per circle on which the image arc length is measured: 64 chords of an imaged circle give its
# length to 4e-4 relative ((2 pi / 64)^2 / 24); the kept points then move along the arc by at most a
# profile spacing against 256 chords, the predicted sigmas by 2e-4 relative and the ranking not at all
# (out of 301 arm candidates at 30 views of the ring grid), and the arm's ranking takes half the time
DENSE = 64


@dataclass(frozen=True)
class SyntheticView:
    """A candidate view's observations (local frame, origin at the first circle's centre) and the
    number of real observations each synthetic row stands for."""

    data: ViewData
    weight: np.ndarray  # (rows,) edge rows, then x and y of every corner


def edge_spacing(target: Target) -> float:
    """Pixels of arc between the detector's edge profiles on this target (:mod:`..detect.grids`
    doubles the spacing on grid elements)."""
    return 2 * DEFAULT_PARAMS.edge_spacing if target.grids else DEFAULT_PARAMS.edge_spacing


def _edge_angles(length: np.ndarray, arc: np.ndarray, spacing: float, least: int, per_edge: int, max_points: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(circle index, angle, weight) of every kept edge point: per circle the detector's n profiles
    evenly spaced in image arc, thinned evenly to ``per_edge`` (the pipeline), then to
    ``max_points`` (each standing for n_real / n_used)."""
    C = len(length)
    n = np.where(np.isfinite(length), np.clip(length / spacing, least, 2000), least).astype(int)
    n_real = np.minimum(n, per_edge)
    n_used = np.minimum(n_real, max_points) if max_points > 0 else n_real
    m = int(n_used.max())
    i = np.arange(m)[None, :]
    keep = i < n_used[:, None]
    j_real = np.floor(i * n_real[:, None] / n_used[:, None]).astype(int)  # linspace(0, n_real, n_used)
    j = np.floor(j_real * n[:, None] / n_real[:, None]).astype(int)  # linspace(0, n, n_real)
    s = j * (np.where(np.isfinite(length), length, 0.0) / n)[:, None]
    # one interpolation over all circles: each row's cumulative arc lifted above the previous ones
    lift = (np.arange(C) * (np.nanmax(np.where(np.isfinite(arc), arc, 0.0)) + 1.0))[:, None]
    dense = np.linspace(0.0, 2 * np.pi, arc.shape[1])
    flat_arc = np.where(np.isfinite(arc), arc, 0.0) + lift
    ang = np.interp((s + lift)[keep], flat_arc.ravel(), np.tile(dense, C))
    k = np.repeat(np.arange(C), n_used)
    return k, ang, (n_real / n_used)[k]


def circle_subset(target: Target, max_elements: int) -> np.ndarray:
    """Indices of the circles of about ``max_elements`` evenly spread grid elements (all circles of
    a target without a grid, or when ``max_elements`` is 0), and each kept element's weight."""
    n = len(target.circles)
    if not target.grids or max_elements <= 0:
        return np.arange(n)
    base = 2 * len(target.rings) + len(target.discs)
    per = [g.circles_per_element for g in target.grids]
    elems = []
    start = base
    for g, p in zip(target.grids, per, strict=True):
        elems += [start + p * e + np.arange(p) for e in range(g.rows * g.cols)]
        start += p * g.rows * g.cols
    pick = np.unique(np.linspace(0, len(elems), min(max_elements, len(elems)), endpoint=False).astype(int))
    return np.r_[np.arange(base), np.concatenate([elems[e] for e in pick])].astype(int)


def synthesise_view(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray,
                    options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                    max_points: int = 0, max_elements: int = 0) -> SyntheticView:
    """The observations the pipeline would take from a view of ``target`` at the pose (R, t)
    (target's local frame, origin at its first circle's centre, -> camera), as measured by
    ``camera``. ``max_points`` > 0 caps the points per edge, ``max_elements`` > 0 the grid
    elements used (each kept row then weighs for those left out)."""
    return synthesise_views(target, camera, np.asarray(R)[None], np.asarray(t)[None], options, max_points,
                            max_elements)[0]


def synthesise_views(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray,
                     options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                     max_points: int = 0, max_elements: int = 0) -> list[SyntheticView]:
    """:func:`synthesise_view` of many poses (R (V, 3, 3), t (V, 3)) at once: one projection of
    every view's circles, one interpolation of every view's edge points."""
    V = len(R)
    origin = np.array(target.local_origin)
    circles = target.circles
    sub = circle_subset(target, max_elements)
    C = len(sub)
    centers = (np.array([c.center for c in circles]).reshape(-1, 2) - origin)[sub]
    radii = np.array([c.radius for c in circles])[sub]
    dark = np.array([c.dark_inside for c in circles], bool)[sub]
    per_edge = max(8, min(options.max_points_per_edge, options.max_points_per_view // max(len(circles), 1)))

    def project(P: np.ndarray, view: np.ndarray) -> np.ndarray:
        """Pixels of target-plane points P (N, 2) seen in views ``view`` (N,)."""
        X = np.einsum("nij,nj->ni", R[view, :, :2], P) + t[view]
        return camera.project(X)

    views = [ViewData(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, int))
             for _ in range(V)]
    weights = [np.zeros(0) for _ in range(V)]
    if C:
        # every view's circles at the dense angles, then the arc lengths (rows: view-major, circle-minor)
        dense = np.linspace(0.0, 2 * np.pi, DENSE + 1)
        xy = centers[:, None, :] + radii[:, None, None] * np.stack([np.cos(dense), np.sin(dense)], -1)  # (C, A, 2)
        X = (R[:, None, None, :, 0] * xy[None, :, :, 0, None] + R[:, None, None, :, 1] * xy[None, :, :, 1, None]
             + t[:, None, None, :])  # (V, C, A, 3): R [x, y, 0] + t
        q = camera.project(X.reshape(-1, 3)).reshape(V * C, DENSE + 1, 2)
        seg = np.linalg.norm(np.diff(q, axis=1), axis=2)
        arc = np.concatenate([np.zeros((V * C, 1)), np.cumsum(seg, 1)], 1)
        k, ang, wk = _edge_angles(arc[:, -1], arc, edge_spacing(target), 12 if target.grids else 24, per_edge,
                                  max_points)
        view, kc = k // C, k % C
        n_grid = len(circles) - C
        if n_grid:  # the grid circles left out: the kept grid rows stand for them
            base = 2 * len(target.rings) + len(target.discs)
            wk = np.where(kc >= base, wk * (len(circles) - base) / max(C - base, 1), wk)
        pts = centers[kc] + radii[kc, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
        pix = project(pts, view)
        bounds = np.searchsorted(view, np.arange(V + 1))
        for v in range(V):
            sl = slice(bounds[v], bounds[v + 1])
            c = kc[sl]
            views[v] = ViewData(pix[sl], centers[c], radii[c], np.where(dark[c], 1.0, -1.0), sub[c])
            weights[v] = wk[sl]
    board = target.board
    if board is not None and options.use_corners:
        obj = board.corner_points() - origin
        pix = project(np.tile(obj, (V, 1)), np.repeat(np.arange(V), len(obj))).reshape(V, len(obj), 2)
        # a marker board's partial view measures the corners in the image only (a whole board's are all in)
        seen = np.all(np.isfinite(pix), 2) & (pix[..., 0] >= 0) & (pix[..., 0] <= camera.width - 1) \
            & (pix[..., 1] >= 0) & (pix[..., 1] <= camera.height - 1)
        for v in range(V):
            views[v].corners, views[v].corner_obj = pix[v][seen[v]], obj[seen[v]]
            weights[v] = np.concatenate([weights[v], np.ones(2 * int(seen[v].sum()))])
    return [SyntheticView(vd, w) for vd, w in zip(views, weights, strict=True)]
