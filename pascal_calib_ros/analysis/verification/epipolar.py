"""Epipolar error of a calibrated, rectified pair, measured on the shots' own features.

In a rectified pair the two images of one 3D point lie on the same row. Circles have no
corresponding points, but they have corresponding *tangents*: the planes through the baseline
that touch a circle touch it in both views, and in the rectified images those planes are the
rows of the circle's horizontal tangents (:func:`~..geometry.rectify.horizontal_tangent_rows`). So
every circle seen by both cameras gives two row differences: its edge points are carried into
each rectified image (:func:`~..geometry.rectify.rectified_pixels`), a conic is fitted to each
(they are the images of a circle by a pinhole camera there) and the rows of the tangents
compared. Checkerboard corners are points: their rectified rows are compared directly (as ROS
``camera_calibration``'s ``epipolar_error`` does). For a vertical pair, columns instead of rows.
"""

from __future__ import annotations

import numpy as np

from ...calibrate import RigResult
from ...detect import Detection
from ...geometry import StereoRectification, Transform, fit_conics_algebraic, horizontal_tangent_rows, rectified_pixels
from ...targets import Target


def _circles(det: Detection, target: Target, label: Transform, origin: np.ndarray, min_points: int
             ) -> dict[tuple[float, float, float, float], np.ndarray]:
    """Edge points of a detection per circle, keyed by the circle's centre in the shot's labelling
    (local frame turned by the view's relabelling L: centre -> L^-1 centre), radius and side."""
    Li = label.inverse()
    out: dict[tuple[float, float, float, float], np.ndarray] = {}
    for e in det.edges:
        if len(e.points) < min_points:
            continue
        c = target.circles[e.circle]
        x = Li.apply(np.r_[np.asarray(c.center) - origin, 0.0])
        out[(round(float(x[0]), 7), round(float(x[1]), 7), c.radius, float(c.dark_inside))] = e.points
    return out


def _tangent_rows(points: list[np.ndarray]) -> np.ndarray:
    """(G, 2) rows of the horizontal tangents of the conic fitted to each point set (NaN where
    no ellipse fits)."""
    owner = np.repeat(np.arange(len(points)), [len(p) for p in points])
    C, ok = fit_conics_algebraic(np.concatenate(points), owner, len(points))
    return np.array([horizontal_tangent_rows(c) if g else np.full(2, np.nan) for c, g in zip(C, ok, strict=True)])


def epipolar_samples(rig: RigResult, rect: StereoRectification, dets: list[list[Detection]], target: Target,
                     left: int = 0, right: int = 1, min_points: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Row differences (px, left - right; columns for a vertical pair) of every circle tangent
    and checkerboard corner seen by both cameras in the shots both used (module docstring), and
    where each was seen in the left camera's raw image ((N, 2): the circle's mean edge point or
    the corner); ``dets[c][s]`` the detections the rig was calibrated from (all their edge points
    are used)."""
    cams = [rig.cameras[left].camera(), rig.cameras[right].camera()]
    Rs, Ps = (rect.R1, rect.R2), (rect.P1, rect.P2)
    swap = np.array([[0.0, 1.0], [1.0, 0.0]]) if rect.vertical else np.eye(2)
    origin = np.asarray(target.local_origin, float)
    board = target.board
    out: list[np.ndarray] = []
    where: list[np.ndarray] = []
    for s in np.flatnonzero(rig.used[left] & rig.used[right]):
        la, lb = rig.start.labels[(left, int(s))], rig.start.labels[(right, int(s))]
        da, db = dets[left][s], dets[right][s]
        ca, cb = _circles(da, target, la, origin, min_points), _circles(db, target, lb, origin, min_points)
        common = [k for k in ca if k in cb]
        pa = [rectified_pixels(cams[0], Rs[0], Ps[0], ca[k]) @ swap for k in common]
        pb = [rectified_pixels(cams[1], Rs[1], Ps[1], cb[k]) @ swap for k in common]
        good = [bool(np.all(np.isfinite(a)) and np.all(np.isfinite(b))) for a, b in zip(pa, pb, strict=True)]
        if any(good):
            d = _tangent_rows([a for a, g in zip(pa, good, strict=True) if g]) - \
                _tangent_rows([b for b, g in zip(pb, good, strict=True) if g])
            uv = np.array([ca[k].mean(0) for k, g in zip(common, good, strict=True) if g])
            ok = np.all(np.isfinite(d), 1)
            out.append(d[ok].ravel())
            where.append(np.repeat(uv[ok], 2, axis=0))
        if board is not None and da.corners is not None and db.corners is not None:
            # corners in target order; a symmetric board's relabelling maps corner positions
            obj = np.c_[board.corner_points() - origin, np.zeros(len(board.corner_points()))]
            ka = {tuple(np.round(la.inverse().apply(o)[:2], 7)): i for i, o in enumerate(obj)}
            kb = [tuple(np.round(lb.inverse().apply(o)[:2], 7)) for o in obj]
            pairs = [(ka[k], i) for i, k in enumerate(kb) if k in ka]
            if pairs:
                ia, ib = np.array(pairs).T
                qa = rectified_pixels(cams[0], Rs[0], Ps[0], np.asarray(da.corners)[ia]) @ swap
                qb = rectified_pixels(cams[1], Rs[1], Ps[1], np.asarray(db.corners)[ib]) @ swap
                d = qa[:, 1] - qb[:, 1]
                ok = np.isfinite(d)
                out.append(d[ok])
                where.append(np.asarray(da.corners)[ia][ok])
    if not out:
        return np.zeros((0, 2)), np.zeros(0)
    return np.concatenate(where), np.concatenate(out)


def epipolar_residuals(rig: RigResult, rect: StereoRectification, dets: list[list[Detection]], target: Target,
                       left: int = 0, right: int = 1) -> np.ndarray:
    """The row differences of :func:`epipolar_samples` (px)."""
    return epipolar_samples(rig, rect, dets, target, left, right)[1]


def epipolar_rms(rig: RigResult, rect: StereoRectification, dets: list[list[Detection]], target: Target,
                 left: int = 0, right: int = 1) -> float:
    """RMS of :func:`epipolar_residuals` (NaN without a shot both cameras used)."""
    d = epipolar_residuals(rig, rect, dets, target, left, right)
    return float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
