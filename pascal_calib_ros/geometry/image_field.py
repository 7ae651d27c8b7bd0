"""Regions of an image: pixel grids, the convex hulls of point sets and their union (the observed field:
the union over the used views of the convex hull of their feature points, where a lens model is known)."""

from __future__ import annotations

import cv2
import numpy as np

from .image_size import ImageSize


def grid_shape(size: ImageSize, step: float) -> tuple[int, int]:
    """(rows, cols) of :func:`grid_pixels` without a mask."""
    width, height = size
    return len(np.arange(step / 2, height, step)), len(np.arange(step / 2, width, step))


def grid_pixels(size: ImageSize, step: float, mask: np.ndarray | None = None) -> np.ndarray:
    """Pixels (N, 2) at the centres of step x step cells over a width x height image, row by row;
    with ``mask`` (height, width), only those where it is true. The one grid the distortion field,
    the projection uncertainty and the projection difference are evaluated on."""
    width, height = size
    us, vs = np.meshgrid(np.arange(step / 2, width, step), np.arange(step / 2, height, step))
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    if mask is not None:
        uv = uv[mask[uv[:, 1].astype(int), uv[:, 0].astype(int)]]
    return uv


def view_hulls(points_per_view: list[np.ndarray]) -> list[np.ndarray]:
    """The convex hull (K, 2) of each view's finite points (views with fewer than 3 left out)."""
    hulls = []
    for p in points_per_view:
        p = np.asarray(p, float).reshape(-1, 2)
        p = p[np.all(np.isfinite(p), 1)]
        if len(p) >= 3:
            hulls.append(cv2.convexHull(p.astype(np.float32)).reshape(-1, 2).astype(float))
    return hulls


def hulls_mask(hulls: list[np.ndarray], size: ImageSize, margin: float = 0.0) -> np.ndarray:
    """(height, width) bool: pixels inside some polygon of ``hulls``, grown by ``margin`` pixels."""
    width, height = size
    mask = np.zeros((height, width), np.uint8)
    for h in hulls:
        cv2.fillConvexPoly(mask, np.round(np.asarray(h, float)).astype(np.int32).reshape(-1, 1, 2), 1)
    if margin > 0 and mask.any():
        k = round(2 * margin + 1)
        return np.asarray(cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))), bool)
    return mask.astype(bool)


def observed_field_mask(points_per_view: list[np.ndarray], size: ImageSize, margin: float = 0.0
                        ) -> np.ndarray:
    """(height, width) bool: pixels inside the convex hull of some view's points, grown by
    ``margin`` pixels."""
    return hulls_mask(view_hulls(points_per_view), size, margin)
