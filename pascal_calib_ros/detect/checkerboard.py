"""Checkerboard inner corners (OpenCV ``findChessboardCornersSB``) in the target's order.

OpenCV may return the grid from either end (a 180 degree ambiguity for non-square grids). When
the view also has the ring, the order is fixed by mapping the ring's centre with the homography of
each candidate order and keeping the one that lands on the detected centre.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..geometry.circular import CircularPointError, centre_image_from_ring
from ..targets import Target

if TYPE_CHECKING:
    from .rings import Detection


def find_checkerboard(gray8: np.ndarray, target: Target, det: Detection | None = None) -> np.ndarray | None:
    """(N, 2) inner corners in ``Checkerboard.corner_points`` order, or None if not found."""
    board = target.checkerboard
    if board is None:
        return None
    size = board.inner_corners
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, corners = cv2.findChessboardCornersSB(gray8, size, flags=flags)
    if not found or corners is None:
        return None
    corners = corners.reshape(-1, 2).astype(float)
    if det is None or not target.rings or det.edge(0) is None or det.edge(1) is None:
        return corners
    e0, e1 = det.edge(0), det.edge(1)
    assert e0 is not None and e1 is not None
    try:
        c = centre_image_from_ring(e0.conic, e1.conic)
    except CircularPointError:
        return corners
    obj = board.corner_points()
    best: tuple[float, np.ndarray] | None = None
    for cand in (corners, corners[::-1].copy()):
        H, _ = cv2.findHomography(obj, cand)
        if H is None:
            continue
        p = H @ np.array([target.rings[0].center[0], target.rings[0].center[1], 1.0])
        d = float(np.hypot(*(p[:2] / p[2] - c[:2])))
        if best is None or d < best[0]:
            best = (d, cand)
    return None if best is None else best[1]
