"""Camera: intrinsics K, a lens model (:mod:`.lens`) and its coefficients D, vectorised.

u = fx x_d + s y_d + cx,  v = fy y_d + cy   (OpenCV / ROS convention), where (x_d, y_d) are the
lens model's distorted normalised coordinates of a camera-frame point. Every model's formulas
live in :mod:`.lens`; this module only adds K.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .image_size import ImageSize
from .lens import PLUMB_BOB, LensModel, model_for_coefficients

INTRINSIC_BASE = ("fx", "fy", "cx", "cy", "skew")


@dataclass(frozen=True)
class Camera:
    """Intrinsics K (3x3), distortion coefficients D of the lens model named ``model`` (ROS
    ``distortion_model``; default plumb_bob, D = (k1, k2, p1, p2, k3))."""

    K: np.ndarray
    D: np.ndarray = field(default_factory=lambda: np.zeros(5))
    width: int = 0
    height: int = 0
    model: str = "plumb_bob"

    def __post_init__(self) -> None:
        self.lens.check(self.D)

    @property
    def lens(self) -> LensModel:
        return model_for_coefficients(self.D, self.model)

    @staticmethod
    def from_params(fx: float, fy: float, cx: float, cy: float, skew: float = 0.0,
                    dist: np.ndarray | list[float] | None = None, width: int = 0, height: int = 0,
                    model: str = "plumb_bob") -> Camera:
        K = np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        lens = model_for_coefficients(np.zeros(5), model)
        D = np.zeros(lens.n) if dist is None else np.asarray(dist, float).reshape(-1)
        return Camera(K, D, width, height, lens.name)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) -> pixels (N, 2)."""
        return normalized_to_pixels(self.lens.distort(np.asarray(X, float), self.D), self.K)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) -> unit rays (..., 3) in the camera frame (NaN where the model cannot
        be inverted); rays may point beyond 90 degrees (fisheye)."""
        return self.lens.undistort(pixels_to_normalized(uv, self.K), self.D)

    def undistort_pixels(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> pinhole normalised coordinates x/z, y/z (N, 2); NaN for rays at or
        beyond 90 degrees."""
        rays = self.unproject(uv)
        z = np.where(rays[..., 2] > 0, rays[..., 2], np.nan)
        return rays[..., :2] / z[..., None]

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


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
    """plumb_bob distortion of pinhole normalised coordinates (..., 2)."""
    return PLUMB_BOB.distort_normalized(np.asarray(xy, float), D)


def undistort(xd: np.ndarray, D: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Invert :func:`distort` (plumb_bob) by Newton's method."""
    return PLUMB_BOB.undistort_normalized(xd, D, iterations)


def _affine_jacobian(dxd: np.ndarray, K: np.ndarray) -> np.ndarray:
    """The affine part of K applied to d x_d / d(...) (N, 2, k): rows (fx, s) and (0, fy)."""
    out = np.empty_like(dxd)
    out[:, 0] = K[0, 0] * dxd[:, 0] + K[0, 1] * dxd[:, 1] if K[0, 1] else K[0, 0] * dxd[:, 0]
    out[:, 1] = K[1, 1] * dxd[:, 1]
    return out


def project_with_jacobians(X: np.ndarray, K: np.ndarray, D: np.ndarray, lens: LensModel = PLUMB_BOB
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project camera-frame points (N, 3) and differentiate analytically.

    Returns the pixels q (N, 2), dq/dX (N, 2, 3) and dq/d(fx, fy, cx, cy, skew, D...)
    (N, 2, 5 + n), by the chain rule through the lens model's x_d(X) and K.
    """
    xd, dxdX, dxdD = lens.distort_with_jacobians(np.asarray(X, float), D)
    q = normalized_to_pixels(xd, K)
    dI = np.zeros((len(q), 2, 5 + lens.n))
    dI[:, 0, 0], dI[:, 0, 2], dI[:, 0, 4] = xd[:, 0], 1.0, xd[:, 1]
    dI[:, 1, 1], dI[:, 1, 3] = xd[:, 1], 1.0
    dI[:, :, 5:] = _affine_jacobian(dxdD, K)
    return q, _affine_jacobian(dxdX, K), dI


def project_with_point_jacobian(X: np.ndarray, K: np.ndarray, D: np.ndarray, lens: LensModel = PLUMB_BOB
                                ) -> tuple[np.ndarray, np.ndarray]:
    """Pixels q (N, 2) and dq/dX (N, 2, 3) of camera-frame points (N, 3): :func:`project_with_jacobians`
    without the intrinsics' Jacobian."""
    xd, dxdX = lens.distort_with_point_jacobian(np.asarray(X, float), D)
    q = np.empty_like(xd)
    q[:, 0] = K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2] if K[0, 1] else K[0, 0] * xd[:, 0] + K[0, 2]
    q[:, 1] = K[1, 1] * xd[:, 1] + K[1, 2]
    return q, _affine_jacobian(dxdX, K)


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


def model_error(cam_a: Camera, cam_b: Camera, size: ImageSize, step: int = 16,
                mask: np.ndarray | None = None) -> float:
    """RMS pixel displacement over the image between two cameras (same rays, both models).

    For a grid of pixels of camera A, the ray is reprojected by camera B; the RMS of the
    displacement measures how differently the two models map the world into the image. ``mask``
    (height, width), if given, restricts the grid to pixels where it is true (e.g. the observed
    field); pixels whose ray either model cannot map are left out.
    """
    width, height = size
    us, vs = np.meshgrid(np.arange(0, width, step) + 0.5, np.arange(0, height, step) + 0.5)
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    if mask is not None:
        uv = uv[mask[vs.ravel().astype(int), us.ravel().astype(int)]]
    rays = cam_a.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not cam_b.lens.wide:
        ok &= rays[:, 2] > 1e-6
    uv_b = cam_b.project(rays[ok])
    d2 = np.sum((uv_b - uv[ok]) ** 2, axis=1)
    return float(np.sqrt(np.mean(d2))) if len(d2) else float("nan")


def calibration_errors(truth: Camera, K: np.ndarray, D: np.ndarray, model: str = "",
                       mask: np.ndarray | None = None) -> dict[str, float]:
    """Errors of an estimated camera (K, D) against the true one: focal lengths in percent,
    principal point in pixels, and the model error of :func:`model_error` over the image."""
    return {
        "fx_err_pct": 100 * (K[0, 0] / truth.K[0, 0] - 1),
        "fy_err_pct": 100 * (K[1, 1] / truth.K[1, 1] - 1),
        "cx_err_px": float(K[0, 2] - truth.K[0, 2]),
        "cy_err_px": float(K[1, 2] - truth.K[1, 2]),
        "pp_err_px": float(np.hypot(K[0, 2] - truth.K[0, 2], K[1, 2] - truth.K[1, 2])),
        "model_err_px": model_error(truth, Camera(K, D, truth.width, truth.height,
                                                  model_for_coefficients(D, model).name),
                                    truth.size, mask=mask),
    }


RECTIFIED_MAX_HALF_FIELD = np.radians(60.0)


def rectified_projection(camera: Camera) -> np.ndarray:
    """P (3x4) of the ``sensor_msgs/CameraInfo`` rectified image. Pinhole models: P = [K | 0].
    A fisheye's rays at or beyond 90 degrees have no pinhole image, so its P is a pinhole view
    with the same principal point and image size whose horizontal half-field is the fisheye's own
    at the nearer left/right image border, capped at RECTIFIED_MAX_HALF_FIELD (60 degrees: wider
    pinhole views spend their pixels on the rim); fy/fx as in K. K itself stays the fisheye's."""
    K = camera.K
    P = np.concatenate([K, np.zeros((3, 1))], 1)
    if not camera.lens.wide:
        return P
    cx, cy = K[0, 2], K[1, 2]
    rays = camera.unproject(np.array([[0.0, cy], [camera.width - 1.0, cy]]))
    angles = np.arccos(np.clip(rays[:, 2], -1.0, 1.0))
    half = float(np.nanmin(np.where(np.isfinite(angles), angles, np.nan))) if np.any(np.isfinite(angles)) else 0.0
    half = min(half if half > 0 else RECTIFIED_MAX_HALF_FIELD, RECTIFIED_MAX_HALF_FIELD)
    half_width = min(cx, camera.width - 1.0 - cx)
    f = half_width / np.tan(half)
    P[0, 0], P[1, 1], P[0, 1] = f, f * K[1, 1] / K[0, 0], 0.0
    return P
