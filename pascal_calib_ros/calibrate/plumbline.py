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

from dataclasses import replace

import numpy as np

from ..detect.rings import Detection
from ..geometry.conic import ellipses_from_conics, fit_conics_algebraic
from ..targets import Target


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
