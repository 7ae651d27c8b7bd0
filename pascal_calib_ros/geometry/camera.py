"""Pinhole camera with plumb_bob (Brown-Conrady) distortion, vectorised.

x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
u = fx x_d + s y_d + cx,  v = fy y_d + cy        (OpenCV / ROS convention, D = k1 k2 p1 p2 k3)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Camera:
    """Intrinsics K (3x3) and plumb_bob distortion D = (k1, k2, p1, p2, k3)."""

    K: np.ndarray
    D: np.ndarray = field(default_factory=lambda: np.zeros(5))
    width: int = 0
    height: int = 0

    @staticmethod
    def from_params(fx: float, fy: float, cx: float, cy: float, skew: float = 0.0,
                    dist: np.ndarray | list[float] | None = None, width: int = 0, height: int = 0) -> Camera:
        K = np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        D = np.zeros(5) if dist is None else np.asarray(dist, float).reshape(5)
        return Camera(K, D, width, height)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) -> pixels (N, 2)."""
        X = np.asarray(X, float)
        xn = X[:, :2] / X[:, 2:3]
        return normalized_to_pixels(distort(xn, self.D), self.K)

    def undistort_pixels(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> undistorted normalised coordinates (N, 2)."""
        return undistort(pixels_to_normalized(uv, self.K), self.D)


def pixels_to_normalized(uv: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Invert the affine part of K: pixels -> distorted normalised coordinates."""
    uv = np.asarray(uv, float)
    y = (uv[..., 1] - K[1, 2]) / K[1, 1]
    x = (uv[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.stack([x, y], axis=-1)


def normalized_to_pixels(xy: np.ndarray, K: np.ndarray) -> np.ndarray:
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], axis=-1)


def distort(xy: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Apply plumb_bob distortion to normalised coordinates (..., 2)."""
    k1, k2, p1, p2, k3 = (float(v) for v in np.asarray(D, float).reshape(-1)[:5])
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def distort_jacobian(xy: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, ...]:
    """Partial derivatives (dxd/dx, dxd/dy, dyd/dx, dyd/dy) of :func:`distort`."""
    k1, k2, p1, p2, k3 = (float(v) for v in np.asarray(D, float).reshape(-1)[:5])
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    a = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
    b = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    c = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    d = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
    return a, b, c, d


def project_with_jacobians(X: np.ndarray, K: np.ndarray, D: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project camera-frame points (N, 3) and differentiate analytically.

    Returns the pixels q (N, 2), dq/dX (N, 2, 3) and dq/d(fx, fy, cx, cy, skew, k1, k2, p1, p2, k3)
    (N, 2, 10), by the chain rule through x = X/Z, :func:`distort` and K (module docstring).
    """
    fx, s, fy = K[0, 0], K[0, 1], K[1, 1]
    z = X[:, 2]
    xn = X[:, :2] / z[:, None]
    xd = distort(xn, D)
    q = normalized_to_pixels(xd, K)
    a, b, c, d = distort_jacobian(xn, D)
    x, y = xn[:, 0], xn[:, 1]
    # dq/dx (normalised), then dx/dX = [[1/Z, 0, -x/Z], [0, 1/Z, -y/Z]]
    m00, m01 = fx * a + s * c, fx * b + s * d
    m10, m11 = fy * c, fy * d
    iz = 1.0 / z
    dX = np.empty((len(X), 2, 3))
    dX[:, 0, 0], dX[:, 0, 1] = m00 * iz, m01 * iz
    dX[:, 0, 2] = -(m00 * x + m01 * y) * iz
    dX[:, 1, 0], dX[:, 1, 1] = m10 * iz, m11 * iz
    dX[:, 1, 2] = -(m10 * x + m11 * y) * iz
    r2 = x * x + y * y
    r4 = r2 * r2
    # d(xd, yd)/d(k1, k2, p1, p2, k3)
    dxd = np.stack([x * r2, x * r4, 2 * x * y, r2 + 2 * x * x, x * r4 * r2], 1)
    dyd = np.stack([y * r2, y * r4, r2 + 2 * y * y, 2 * x * y, y * r4 * r2], 1)
    dI = np.zeros((len(X), 2, 10))
    dI[:, 0, 0], dI[:, 0, 2], dI[:, 0, 4] = xd[:, 0], 1.0, xd[:, 1]
    dI[:, 1, 1], dI[:, 1, 3] = xd[:, 1], 1.0
    dI[:, 0, 5:] = fx * dxd + s * dyd
    dI[:, 1, 5:] = fy * dyd
    return q, dX, dI


def undistort(xd: np.ndarray, D: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Invert :func:`distort` by Newton's method (vectorised, from x = x_d)."""
    xd = np.asarray(xd, float)
    if not np.any(np.asarray(D) != 0):
        return xd.copy()
    xy = xd.copy()
    for _ in range(iterations):
        f = distort(xy, D) - xd
        a, b, c, d = distort_jacobian(xy, D)
        det = a * d - b * c
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (d * f[..., 0] - b * f[..., 1]) / det
        dy = (-c * f[..., 0] + a * f[..., 1]) / det
        xy[..., 0] -= dx
        xy[..., 1] -= dy
        if np.max(np.abs(dx)) + np.max(np.abs(dy)) < 1e-14:
            break
    return xy


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation matrix from a rotation vector (axis * angle)."""
    r = np.asarray(rvec, float).reshape(3)
    th = float(np.linalg.norm(r))
    if th < 1e-12:
        kx = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        return np.eye(3) + kx
    k = r / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * (kx @ kx)


def rotation_to_rvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`rodrigues`)."""
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    th = float(np.arccos(c))
    if th < 1e-9:
        return np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
    if np.pi - th < 1e-6:
        w, v = np.linalg.eigh((R + R.T) / 2)
        axis = v[:, np.argmax(w)]
        return axis * th
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * np.sin(th))
    return axis * th


def model_error(cam_a: Camera, cam_b: Camera, width: int, height: int, step: int = 16) -> float:
    """RMS pixel displacement over the image between two cameras (same rays, both models).

    For a grid of pixels of camera A, the ray is reprojected by camera B; the RMS of the
    displacement measures how differently the two models map the world into the image.
    """
    us, vs = np.meshgrid(np.arange(0, width, step) + 0.5, np.arange(0, height, step) + 0.5)
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    xn = cam_a.undistort_pixels(uv)
    X = np.concatenate([xn, np.ones((len(xn), 1))], 1)
    uv_b = cam_b.project(X)
    return float(np.sqrt(np.mean(np.sum((uv_b - uv) ** 2, axis=1))))


def calibration_errors(truth: Camera, K: np.ndarray, D: np.ndarray) -> dict[str, float]:
    """Errors of an estimated camera (K, D) against the true one: focal lengths in percent,
    principal point in pixels, and the model error of :func:`model_error` over the image."""
    return {
        "fx_err_pct": 100 * (K[0, 0] / truth.K[0, 0] - 1),
        "fy_err_pct": 100 * (K[1, 1] / truth.K[1, 1] - 1),
        "cx_err_px": float(K[0, 2] - truth.K[0, 2]),
        "cy_err_px": float(K[1, 2] - truth.K[1, 2]),
        "pp_err_px": float(np.hypot(K[0, 2] - truth.K[0, 2], K[1, 2] - truth.K[1, 2])),
        "model_err_px": model_error(truth, Camera(K, D, truth.width, truth.height), truth.width, truth.height),
    }
