"""Small image and contour tools of the blob search (:mod:`.target_detector`): the grey image as
floats, its grey range, the Sobel gradient at pixels, batched ellipse fits of contours and an
ellipse's room to the image border."""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry import Ellipse, ellipses_from_conics, fit_conics_algebraic, group_medians, sampson_distances


def to_float(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype == np.uint8:
        return image.astype(np.float32)
    if image.dtype == np.uint16:
        return image.astype(np.float32) / 257.0
    return image.astype(np.float32)


def grey_range(image: np.ndarray, gray: np.ndarray) -> float:
    """Highest minus lowest grey level of ``gray`` (``to_float(image)``), by one
    ``cv2.minMaxLoc`` pass over the smallest array holding them: a grey uint8 or uint16 image
    itself (5 MP: 0.05 ms instead of numpy's two passes over the floats, 0.8 ms)."""
    src = image if image.ndim == 2 and image.dtype in (np.uint8, np.uint16) else gray
    lo, hi, _, _ = cv2.minMaxLoc(src)
    return float(hi - lo) / (257.0 if src.dtype == np.uint16 else 1.0)


def sobel_magnitude_at(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """|3x3 Sobel gradient| / 8 (grey levels per pixel) of ``img`` at integer pixels (x, y)."""
    h, w = img.shape
    x0, x1, x2 = np.maximum(x - 1, 0), x, np.minimum(x + 1, w - 1)
    y0, y1, y2 = np.maximum(y - 1, 0), y, np.minimum(y + 1, h - 1)
    gx = (img[y0, x2] - img[y0, x0]) + 2 * (img[y1, x2] - img[y1, x0]) + (img[y2, x2] - img[y2, x0])
    gy = (img[y2, x0] - img[y0, x0]) + 2 * (img[y2, x1] - img[y0, x1]) + (img[y2, x2] - img[y0, x2])
    return np.hypot(gx.astype(float), gy.astype(float)) / 8.0


def room_to_border(e: Ellipse, frame: tuple[int, int]) -> float:
    """The least distance (px) from the ellipse ``e`` to the border of an image ``frame`` (width,
    height), negative where it leaves the image: by its bounding box, half-extents
    sqrt(a^2 cos^2 t + b^2 sin^2 t) along x and sqrt(a^2 sin^2 t + b^2 cos^2 t) along y (t its angle)."""
    w, h = frame
    ext_x = np.sqrt((e.a * np.cos(e.angle)) ** 2 + (e.b * np.sin(e.angle)) ** 2)
    ext_y = np.sqrt((e.a * np.sin(e.angle)) ** 2 + (e.b * np.cos(e.angle)) ** 2)
    return float(min(e.cx - ext_x, e.cy - ext_y, w - 1 - e.cx - ext_x, h - 1 - e.cy - ext_y))


def ellipses_of(contours: list[np.ndarray]) -> list[tuple[Ellipse, float] | None]:
    """Ellipses of many contours by one batched algebraic fit: the fitted ellipse and the median
    |Sampson distance| of its contour (None where no ellipse fits or the contour is too short)."""
    if not contours:
        return []
    n = len(contours)
    owner = np.repeat(np.arange(n), [len(c) for c in contours])
    pts = np.concatenate(contours)
    C, ok = fit_conics_algebraic(pts, owner, n)
    par, real = ellipses_from_conics(np.where(ok[:, None, None], C, np.eye(3)))
    ok &= real & np.isfinite(par).all(1) & (par[:, 2] > 0) & (par[:, 3] > 0)
    ok &= np.array([len(c) >= 8 for c in contours])
    res = group_medians(np.abs(sampson_distances(C, pts, owner)), owner, n)
    return [(Ellipse(*(float(v) for v in par[k])), float(res[k])) if ok[k] else None for k in range(n)]
