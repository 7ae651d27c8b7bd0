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

from ..calibrate.pipeline import CalibrationOptions
from ..calibrate.refine import ViewData
from ..detect.detection import DEFAULT_PARAMS
from ..geometry.camera import Camera
from ..targets import Target

DENSE = 256  # angles per circle on which the image arc length is measured


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


def circle_points(camera: Camera, R: np.ndarray, t: np.ndarray, centers: np.ndarray, radii: np.ndarray,
                  angles: np.ndarray) -> np.ndarray:
    """Pixels (C, A, 2) of the circles (centres (C, 2), radii (C,), target plane) at ``angles``
    (A,) or (C, A), pose X_cam = R X + t."""
    ang = np.broadcast_to(angles, (len(centers), np.shape(angles)[-1]))
    xy = centers[:, None, :] + radii[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    X = np.concatenate([xy, np.zeros((*xy.shape[:2], 1))], -1) @ R.T + t
    return camera.project(X.reshape(-1, 3)).reshape(*xy.shape[:2], 2)


def _even_angles(camera: Camera, R: np.ndarray, t: np.ndarray, centers: np.ndarray, radii: np.ndarray,
                 spacing: float, least: int) -> list[np.ndarray]:
    """Per circle the angles of points evenly spaced by ``spacing`` px of image arc (at least
    ``least``)."""
    dense = np.linspace(0.0, 2 * np.pi, DENSE + 1)
    q = circle_points(camera, R, t, centers, radii, dense)
    seg = np.linalg.norm(np.diff(q, axis=1), axis=2)
    arc = np.concatenate([np.zeros((len(q), 1)), np.cumsum(seg, 1)], 1)
    out = []
    for c in range(len(q)):
        length = float(arc[c, -1])
        n = int(np.clip(length / spacing, least, 2000)) if np.isfinite(length) else least
        s = np.arange(n) * length / n
        out.append(np.interp(s, arc[c], dense))
    return out


def synthesise_view(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray,
                    options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                    max_points: int = 0) -> SyntheticView:
    """The observations the pipeline would take from a view of ``target`` at the pose (R, t)
    (target's local frame, origin at its first circle's centre, -> camera), as measured by
    ``camera``. ``max_points`` > 0 caps the points per edge (each then weighs more)."""
    origin = np.array(target.circles[0].center if target.circles else (0.0, 0.0))
    circles = target.circles
    centers = np.array([c.center for c in circles]).reshape(-1, 2) - origin
    radii = np.array([c.radius for c in circles])
    spacing = edge_spacing(target)
    per_edge = max(8, min(options.max_points_per_edge, options.max_points_per_view // max(len(circles), 1)))
    pts, ctr, rad, sgn, ids, wts = [np.zeros((0, 2))], [np.zeros((0, 2))], [np.zeros(0)], [np.zeros(0)], \
        [np.zeros(0, int)], [np.zeros(0)]
    if len(circles):
        angles = _even_angles(camera, R, t, centers, radii, spacing, 12 if target.grids else 24)
        for k, c in enumerate(circles):
            a = angles[k]
            n_real = min(len(a), per_edge)
            a = a[np.linspace(0, len(a), n_real, endpoint=False).astype(int)]
            n_used = min(n_real, max_points) if max_points > 0 else n_real
            a = a[np.linspace(0, len(a), n_used, endpoint=False).astype(int)]
            pts.append(circle_points(camera, R, t, centers[k:k + 1], radii[k:k + 1], a)[0])
            ctr.append(np.tile(centers[k], (n_used, 1)))
            rad.append(np.full(n_used, c.radius))
            sgn.append(np.full(n_used, 1.0 if c.dark_inside else -1.0))
            ids.append(np.full(n_used, k))
            wts.append(np.full(n_used, n_real / n_used))
    vd = ViewData(np.concatenate(pts), np.concatenate(ctr), np.concatenate(rad), np.concatenate(sgn),
                  np.concatenate(ids))
    weight = np.concatenate(wts)
    board = target.checkerboard
    if board is not None and options.use_corners:
        obj = board.corner_points() - origin
        X = np.concatenate([obj, np.zeros((len(obj), 1))], 1) @ R.T + t
        vd.corners = camera.project(X)
        vd.corner_obj = obj
        weight = np.concatenate([weight, np.ones(2 * len(obj))])
    return SyntheticView(vd, weight)
