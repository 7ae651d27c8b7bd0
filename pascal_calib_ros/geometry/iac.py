"""Image of the absolute conic w = K^-T K^-1 from circular-point images, and K from w.

Each view's i' gives i'^T w i' = 0 (Zhang 2000, eq. 3; seed paper, eq. 9): with
w = [[w1, w2, w4], [w2, w3, w5], [w4, w5, w6]] and i' = (x, y, z), the row
[x^2, 2xy, y^2, 2xz, 2yz, z^2] . (w1..w6) = 0, whose real and imaginary parts are two real
equations. Three views in general position fix w up to scale; K follows by Cholesky.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PascalCalibError
from .image_size import ImageSize

# Thresholds on the degeneracy ratio (smallest non-null / largest singular value), PAPER.md
DEGENERACY_REJECT = 0.01
DEGENERACY_WARN = 0.05


class DegenerateViewsError(PascalCalibError):
    """The views do not determine w (too few, parallel planes, fronto-parallel only)."""


class IndefiniteOmegaError(DegenerateViewsError):
    """The views determine a w, but it is not positive definite: no camera has it (noise, or conics
    bent by lens distortion the closed form does not model)."""


@dataclass(frozen=True)
class IacSolution:
    K: np.ndarray
    omega: np.ndarray
    degeneracy_ratio: float
    warning: str = ""


def image_normalization(size: ImageSize) -> np.ndarray:
    """T taking pixels to coordinates centred on the image, scaled by (W + H) / 4."""
    width, height = size
    s = 4.0 / (width + height)
    return np.array([[s, 0, -s * width / 2], [0, s, -s * height / 2], [0, 0, 1.0]])


def _rows(i: np.ndarray, zero_skew: bool) -> np.ndarray:
    x, y, z = i
    row = np.array([x * x, 2 * x * y, y * y, 2 * x * z, 2 * y * z, z * z])
    if zero_skew:
        row = np.delete(row, 1)
    return np.stack([row.real, row.imag])


def _assemble(w: np.ndarray, zero_skew: bool) -> np.ndarray:
    if zero_skew:
        w = np.insert(w, 1, 0.0)
    w1, w2, w3, w4, w5, w6 = w
    return np.array([[w1, w2, w4], [w2, w3, w5], [w4, w5, w6]])


def constraint_matrix(points: list[np.ndarray], T: np.ndarray, zero_skew: bool = False) -> np.ndarray:
    """Stacked 2N x 6 (or 2N x 5 with zero skew) matrix A with A w = 0, in normalised
    coordinates with each i' scaled to unit norm."""
    rows = []
    for i in points:
        q = T @ np.asarray(i, complex)
        q = q / np.linalg.norm(q)
        rows.append(_rows(q, zero_skew))
    return np.concatenate(rows, axis=0)


def degeneracy_ratio(A: np.ndarray) -> float:
    """Smallest non-null singular value over the largest (5th/1st for 6 unknowns)."""
    s = np.linalg.svd(A, compute_uv=False)
    n = A.shape[1]
    if len(s) < n - 1:
        return 0.0
    return float(s[n - 2] / s[0])


def k_from_omega(omega: np.ndarray) -> np.ndarray:
    """K from w = K^-T K^-1 by Cholesky: w = L L^T, K^-1 = L^T, K = (L^T)^-1, K[2,2] = 1.
    Raises :class:`DegenerateViewsError` if w is not positive definite (never clipped)."""
    w = (omega + omega.T) / 2
    if np.trace(w) < 0:
        w = -w
    try:
        L = np.linalg.cholesky(w)
    except np.linalg.LinAlgError:
        raise IndefiniteOmegaError(
            "the image of the absolute conic is not positive definite: the views are too noisy or "
            "nearly degenerate; add views with the target tilted 20-45 degrees in different directions"
        ) from None
    K = np.linalg.inv(L.T)
    return K / K[2, 2]


def iac_from_circular_points(points: list[np.ndarray], size: ImageSize,
                             zero_skew: bool = False) -> IacSolution:
    """Solve A w = 0 in normalised coordinates (SVD), check degeneracy and definiteness, K by
    Cholesky. ``points`` holds one i' (complex homogeneous 3-vector, pixels) per view or circle
    pair. Raises :class:`DegenerateViewsError` with advice a user can act on."""
    unknowns = 5 if zero_skew else 6
    needed = int(np.ceil((unknowns - 1) / 2))
    if len(points) < needed:
        raise DegenerateViewsError(
            f"{len(points)} view(s) give {2 * len(points)} equations; w needs {unknowns - 1}: "
            f"capture at least {needed} views with the target at different tilts")
    T = image_normalization(size)
    A = constraint_matrix(points, T, zero_skew)
    if not np.all(np.isfinite(A)):
        raise DegenerateViewsError("a circular point is at infinity or invalid (fronto-parallel view?)")
    ratio = degeneracy_ratio(A)
    if ratio < DEGENERACY_REJECT:
        raise DegenerateViewsError(
            f"degenerate set of views (ratio {ratio:.4f} < {DEGENERACY_REJECT}): all target planes "
            "nearly parallel or fronto-parallel; tilt the target 20-45 degrees about different axes "
            "between views")
    warning = ""
    if ratio < DEGENERACY_WARN:
        warning = (f"weakly constrained set of views (ratio {ratio:.3f} < {DEGENERACY_WARN}): add "
                   "views tilted about other axes")
    _, _, vt = np.linalg.svd(A)
    wn = _assemble(vt[-1], zero_skew)
    omega = T.T @ wn @ T
    K = k_from_omega(omega)
    return IacSolution(K, omega / np.linalg.norm(omega), ratio, warning)


def iac_focal_only(points: list[np.ndarray], size: ImageSize) -> IacSolution:
    """w of a camera with square pixels, no skew and the principal point at the image centre: the
    start when the full w is not positive definite. In coordinates centred on the image,
    K = diag(f, f, 1) and w ~ diag(1, 1, f^2), so each i' = (x, y, z) gives x^2 + y^2 + f^2 z^2 = 0;
    f^2 by least squares over the views (each i' scaled to unit norm):
    f^2 = -Re(sum conj(z^2) (x^2 + y^2)) / sum |z|^4. Raises :class:`IndefiniteOmegaError` when
    f^2 <= 0 (the circular points contradict any such camera)."""
    width, height = size
    c = np.array([width / 2.0, height / 2.0, 0.0])
    num, den = 0.0, 0.0
    for i in points:
        q = np.asarray(i, complex)
        q = q - c * q[2]  # centred on the image
        q = q / np.linalg.norm(q)
        x, y, z = q
        num += float(np.real(np.conj(z * z) * (x * x + y * y)))
        den += float(abs(z) ** 4)
    if den <= 0 or -num / den <= 0:
        raise IndefiniteOmegaError("no focal length fits the circular points (f^2 <= 0)")
    f = float(np.sqrt(-num / den))
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    Ki = np.linalg.inv(K)
    omega = Ki.T @ Ki
    return IacSolution(K, omega / np.linalg.norm(omega), float("nan"))
