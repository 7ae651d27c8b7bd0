"""Plain numbers about a calibration that the CLI, the node and the report share.

- The observed field: the union over the used views of the convex hull of their feature points
  (edge points, checkerboard corners); a lens model is only known there.
- The distortion field: where the ideal model of the same lens family (same K, no coefficients:
  the pinhole for plumb_bob and rational_polynomial, r = f theta for equidistant) would image each
  ray, against where the calibrated model images it; computed only inside the observed field
  (plus a margin), so a fold of the polynomial far outside it cannot set the scale.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..detect.detection import Detection
from ..geometry.camera import Camera


def grid_shape(width: int, height: int, step: float) -> tuple[int, int]:
    """(rows, cols) of :func:`grid_pixels` without a mask."""
    return len(np.arange(step / 2, height, step)), len(np.arange(step / 2, width, step))


def grid_pixels(width: int, height: int, step: float, mask: np.ndarray | None = None) -> np.ndarray:
    """Pixels (N, 2) at the centres of step x step cells over a width x height image, row by row;
    with ``mask`` (height, width), only those where it is true. The one grid the distortion field,
    the projection uncertainty and the projection difference are evaluated on."""
    us, vs = np.meshgrid(np.arange(step / 2, width, step), np.arange(step / 2, height, step))
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    if mask is not None:
        uv = uv[mask[uv[:, 1].astype(int), uv[:, 0].astype(int)]]
    return uv


def feature_points(det: Detection) -> np.ndarray:
    """(N, 2) feature points of a detection: its edge points and checkerboard corners."""
    parts = [np.asarray(e.points, float).reshape(-1, 2) for e in det.edges]
    if det.corners is not None:
        parts.append(np.asarray(det.corners, float).reshape(-1, 2))
    return np.concatenate(parts) if parts else np.zeros((0, 2))


def view_hulls(points_per_view: list[np.ndarray]) -> list[np.ndarray]:
    """The convex hull (K, 2) of each view's finite points (views with fewer than 3 left out)."""
    hulls = []
    for p in points_per_view:
        p = np.asarray(p, float).reshape(-1, 2)
        p = p[np.all(np.isfinite(p), 1)]
        if len(p) >= 3:
            hulls.append(cv2.convexHull(p.astype(np.float32)).reshape(-1, 2).astype(float))
    return hulls


def hulls_mask(hulls: list[np.ndarray], width: int, height: int, margin: float = 0.0) -> np.ndarray:
    """(height, width) bool: pixels inside some polygon of ``hulls``, grown by ``margin`` pixels."""
    mask = np.zeros((height, width), np.uint8)
    for h in hulls:
        cv2.fillConvexPoly(mask, np.round(np.asarray(h, float)).astype(np.int32).reshape(-1, 1, 2), 1)
    if margin > 0 and mask.any():
        k = round(2 * margin + 1)
        return np.asarray(cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))), bool)
    return mask.astype(bool)


def observed_field_mask(points_per_view: list[np.ndarray], width: int, height: int, margin: float = 0.0
                        ) -> np.ndarray:
    """(height, width) bool: pixels inside the convex hull of some view's points, grown by
    ``margin`` pixels."""
    return hulls_mask(view_hulls(points_per_view), width, height, margin)


def distortion_field(cam: Camera, step: int = 32, mask: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Grid of pixels (N, 2) (inside ``mask`` if given) and the displacement (N, 2) from where the
    ideal model of the lens family would image each pixel's ray to the pixel itself; rows whose
    ray the model cannot invert are left out."""
    uv = grid_pixels(cam.width, cam.height, step, mask)
    if not len(uv):
        return uv, np.zeros((0, 2))
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not cam.lens.wide:
        ok &= rays[:, 2] > 1e-6
    ideal = Camera(cam.K, np.zeros(cam.lens.n), cam.width, cam.height, cam.model).project(rays[ok])
    return uv[ok], uv[ok] - ideal


def model_valid(cam: Camera, uv: np.ndarray, tolerance: float = 0.05) -> np.ndarray:
    """(N,) bool: pixels where the lens model holds as a camera model: its ray exists (the model
    is invertible there), projects back onto the pixel within ``tolerance`` px, and lies inside
    the angle up to which the model's radius grows monotonically (``LensModel.max_angle``)."""
    ok, rays = consistent_rays(cam, uv, tolerance)
    if ok.any():
        r = rays[ok] / np.linalg.norm(rays[ok], axis=1, keepdims=True)
        ok[ok] &= np.arccos(np.clip(r[:, 2], -1, 1)) <= cam.lens.max_angle(cam.D)
    return ok


def consistent_rays(cam: Camera, uv: np.ndarray, tolerance: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """(N,) bool and the rays (N, 3): pixels whose ray exists (in front of a pinhole camera) and
    projects back onto the pixel within ``tolerance`` px; where a fitted model folds over, this fails."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    if not len(uv):
        return np.zeros(0, bool), np.zeros((0, 3))
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not cam.lens.wide:
        ok &= rays[:, 2] > 0
    if ok.any():
        ok[ok] &= np.linalg.norm(cam.project(rays[ok]) - uv[ok], axis=1) < tolerance
    return ok, rays
