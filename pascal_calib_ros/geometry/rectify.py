"""Rectification of a calibrated stereo pair: the rotations R1, R2 that make the two cameras'
image rows the epipolar lines, the rectified projections P1, P2 and the reprojection matrix Q,
as ROS ``sensor_msgs/CameraInfo`` (R, P) and ``stereo_image_proc`` use them.

The pair is given by its two cameras and the transform X_right = R X_left + T (metres; OpenCV's
``stereoCalibrate`` convention). In the rectified frames X_l' = R1 X_l and X_r' = R2 X_r the
cameras differ by a translation along x (horizontal pair) or y (vertical) only, and
P1 = K' [I | 0], P2 = K' [I | R2 T]: for a horizontal pair P2[0, 3] = fx' T_x' with
T_x' = -baseline (the right camera to the right), which is how ``image_geometry`` reads the
baseline (baseline = -P2[0, 3] / P2[0, 0]).

- Pinhole lens models (plumb_bob, rational_polynomial): OpenCV's ``stereoRectify`` with
  ``CALIB_ZERO_DISPARITY`` (the two principal points equal) and ``alpha`` (0: every rectified
  pixel valid, the images zoomed in; 1: every source pixel kept), as ROS ``camera_calibration``
  does (alpha 0 by default).
- Equidistant (fisheye) pairs: R1, R2 as OpenCV's ``stereoRectify`` (they depend on R, T alone);
  a pinhole view of rays at or beyond 90 degrees does not exist, so the rectified views are
  pinhole views centred in the image whose horizontal half-field is the smaller of the two
  cameras' own at their nearer left/right image border, capped at 60 degrees
  (:data:`~.camera.RECTIFIED_MAX_HALF_FIELD`, as the monocular P of a fisheye); ``alpha`` does not
  apply. Consumers map with ``cv2.fisheye.initUndistortRectifyMap`` (what ``image_geometry`` does
  for ``equidistant``), identical to this package's model inside 90 degrees.
  (``cv2.fisheye.stereoRectify``'s balance / fov_scale choice is not used: on wide pairs it gives
  rectified views whose focal length collapses or whose field cannot be chosen.)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import PascalCalibError
from .camera import RECTIFIED_MAX_HALF_FIELD, Camera
from .image_size import ImageSize


class RectificationError(PascalCalibError):
    """The pair cannot be rectified (different image sizes, cameras side by side along the view)."""


@dataclass(frozen=True)
class StereoRectification:
    """R1, R2 (3x3), P1, P2 (3x4), Q (4x4) of a pair; ``alpha`` used (NaN where it does not
    apply); ``method`` in words; the rectified views' horizontal half-field (deg)."""

    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Q: np.ndarray
    alpha: float
    width: int
    height: int
    method: str
    half_field_deg: float

    @property
    def vertical(self) -> bool:
        """True for a vertical pair (rectified columns are the epipolar lines)."""
        return abs(self.P2[1, 3]) > abs(self.P2[0, 3])

    @property
    def baseline(self) -> float:
        """Distance of the two rectified camera centres (m), as image_geometry computes it."""
        return float(abs(self.P2[1, 3] / self.P2[1, 1]) if self.vertical else -self.P2[0, 3] / self.P2[0, 0])

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def rectified_pixels(camera: Camera, R: np.ndarray, P: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Raw pixels (N, 2) of ``camera`` -> pixels (N, 2) of its rectified image (R, P of its
    CameraInfo): the pixel's ray turned by R and drawn with P's 3x3 part (NaN where the model has
    no ray or the ray leaves the rectified view's half-space)."""
    rays = camera.unproject(np.asarray(uv, float).reshape(-1, 2)) @ np.asarray(R, float).T
    q = rays @ np.asarray(P, float)[:, :3].T
    z = np.where(q[:, 2] > 1e-9, q[:, 2], np.nan)
    return q[:, :2] / z[:, None]


def _q_matrix(P1: np.ndarray, P2: np.ndarray, vertical: bool) -> np.ndarray:
    """OpenCV's Q (disparity-to-depth) of rectified projections (``stereoRectify`` docs)."""
    f, cx1, cy1 = P1[0, 0], P1[0, 2], P1[1, 2]
    Q = np.zeros((4, 4))
    Q[0, 0] = Q[1, 1] = 1.0
    Q[0, 3], Q[1, 3], Q[2, 3] = -cx1, -cy1, f
    if vertical:
        Ty = P2[1, 3] / P2[1, 1]
        Q[3, 2], Q[3, 3] = -1.0 / Ty, (cy1 - P2[1, 2]) / Ty
    else:
        Tx = P2[0, 3] / P2[0, 0]
        Q[3, 2], Q[3, 3] = -1.0 / Tx, (cx1 - P2[0, 2]) / Tx
    return Q


def _half_field(camera: Camera) -> float:
    """The fisheye's horizontal half-field at its nearer left/right image border (rad), capped."""
    cy = camera.K[1, 2]
    rays = camera.unproject(np.array([[0.0, cy], [camera.width - 1.0, cy]]))
    ang = np.arccos(np.clip(rays[:, 2], -1.0, 1.0))
    ang = ang[np.isfinite(ang)]
    return float(min(np.min(ang) if len(ang) else RECTIFIED_MAX_HALF_FIELD, RECTIFIED_MAX_HALF_FIELD))


def rectify_pair(left: Camera, right: Camera, R: np.ndarray, T: np.ndarray, alpha: float = 0.0
                 ) -> StereoRectification:
    """The rectification of a calibrated pair (module docstring); X_right = R X_left + T."""
    size = (left.width, left.height)
    if size != (right.width, right.height):
        raise RectificationError(f"the cameras' images differ in size ({left.width}x{left.height} and "
                                 f"{right.width}x{right.height}): a rectified pair shares one image size")
    R = np.asarray(R, float)
    T = np.asarray(T, float).reshape(3)
    if float(np.linalg.norm(T)) <= 0 or np.linalg.norm(T[:2]) < 0.2 * abs(T[2]):
        raise RectificationError(f"the cameras are placed along their viewing direction (T = {T.tolist()} m): "
                                 "rectified rows need a baseline across the view (horizontal or vertical pair)")
    if not (0.0 <= alpha <= 1.0):
        raise RectificationError(f"alpha {alpha} is outside 0 (valid pixels only) .. 1 (all source pixels)")
    wide = left.lens.wide or right.lens.wide
    if wide and left.lens.name != right.lens.name:
        raise RectificationError(f"a fisheye and a non-fisheye camera ({left.model}, {right.model}) cannot share "
                                 "OpenCV's rectification maps")
    K1, K2 = left.K.astype(float), right.K.astype(float)
    D1 = np.zeros(5) if wide else np.asarray(left.D, float)
    D2 = np.zeros(5) if wide else np.asarray(right.D, float)
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(K1, D1, K2, D2, size, R, T.reshape(3, 1),
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
    R1, R2, P1, P2, Q = (np.asarray(m, float) for m in (R1, R2, P1, P2, Q))
    vertical = abs(P2[1, 3]) > abs(P2[0, 3])
    if not wide:
        half = float(np.degrees(np.arctan((size[0] / 2) / P1[0, 0])))
        return StereoRectification(R1=R1, R2=R2, P1=P1, P2=P2, Q=Q, alpha=float(alpha), width=size[0], height=size[1],
                                   method=f"cv2.stereoRectify, CALIB_ZERO_DISPARITY, alpha {alpha:g}",
                                   half_field_deg=half)
    half_rad = min(_half_field(left), _half_field(right))
    f = (size[0] - 1) / 2 / np.tan(half_rad)
    Kn = np.array([[f, 0.0, (size[0] - 1) / 2], [0.0, f, (size[1] - 1) / 2], [0.0, 0.0, 1.0]])
    P1 = np.c_[Kn, np.zeros(3)]
    P2 = np.c_[Kn, Kn @ (R2 @ T)]
    P2[2, 3] = 0.0 if abs(P2[2, 3]) < 1e-12 else P2[2, 3]
    return StereoRectification(R1=R1, R2=R2, P1=P1, P2=P2, Q=_q_matrix(P1, P2, vertical), alpha=float("nan"),
                               width=size[0], height=size[1],
                               method=f"pinhole views of +-{np.degrees(half_rad):.0f} deg across (fisheye pair; alpha "
                                      "does not apply)", half_field_deg=float(np.degrees(half_rad)))


def rectify_maps(camera: Camera, R: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.initUndistortRectifyMap`` (``cv2.fisheye.`` for equidistant) of one camera: the
    (map_x, map_y) float32 arrays of its rectified image, as a ROS consumer computes them."""
    size = (camera.width, camera.height)
    K, D = camera.K.astype(float), np.asarray(camera.D, float)
    if camera.lens.wide:
        mx, my = cv2.fisheye.initUndistortRectifyMap(K, D.reshape(4, 1), R, P, size, cv2.CV_32FC1)
    else:
        mx, my = cv2.initUndistortRectifyMap(K, D, R, P, size, cv2.CV_32FC1)
    return np.asarray(mx), np.asarray(my)


def horizontal_tangent_rows(C: np.ndarray) -> np.ndarray:
    """The two rows y of the horizontal tangents of a conic C (x^T C x = 0, x = (u, v, 1)),
    sorted: a line (0, 1, -y) touches C where l^T C* l = 0, C* the adjugate of C (the dual
    conic): C*_11 - 2 y C*_12 + y^2 C*_22 = 0. In a rectified pair the images of one circle
    have these tangents on the same rows (the tangent planes through the baseline are shared)."""
    A = np.linalg.inv(C) * np.linalg.det(C)  # adjugate (C is invertible for an ellipse)
    a, b, c = A[2, 2], -2 * A[1, 2], A[1, 1]
    disc = b * b - 4 * a * c
    if a == 0 or disc < 0:
        return np.full(2, np.nan)
    r = np.sqrt(disc)
    return np.sort(np.array([(-b - r) / (2 * a), (-b + r) / (2 * a)]))
