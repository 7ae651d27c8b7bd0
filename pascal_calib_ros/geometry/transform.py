"""One rigid-transform type for the whole package (hand-eye, robot poses, target poses).

A :class:`Transform` T maps points of a child frame into its parent frame: p_parent = R p_child + t
(the ROS ``geometry_msgs/Transform`` of parent -> child, tf2's ``lookupTransform(parent, child)``).
Composition ``a @ b`` is "b, then a": (a @ b).apply(p) == a.apply(b.apply(p)), so
T_base_cam = T_base_tool @ T_tool_cam. Rotations are :class:`scipy.spatial.transform.Rotation`;
quaternions are in ROS order (x, y, z, w).

Quaternions read from files are checked: a norm within :data:`QUAT_TOLERANCE` (1e-3) of 1 is
normalised silently (files carry 6-7 digits), anything further off is refused with a
:class:`TransformError` (a ``ValueError``): it is a wrong field, not rounding.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import PascalCalibError

QUAT_TOLERANCE = 1e-3


class TransformError(PascalCalibError):
    """A rotation or translation that is not a rigid transform (non-unit quaternion, NaN, ...)."""


def _vec3(t: object, what: str) -> np.ndarray:
    try:
        v = np.asarray(t, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TransformError(f"{what}: expected 3 numbers, got {t!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise TransformError(f"{what}: expected 3 finite numbers, got {t!r}")
    return v


@dataclass(frozen=True)
class Transform:
    """p_parent = rotation.apply(p_child) + translation (metres)."""

    rotation: Rotation = field(default_factory=Rotation.identity)
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "translation", _vec3(self.translation, "translation"))
        if not isinstance(self.rotation, Rotation) or not self.rotation.single:
            raise TransformError("rotation must be a single scipy Rotation")

    # -- constructors ----------------------------------------------------------------------
    @staticmethod
    def identity() -> Transform:
        return Transform(Rotation.identity(), np.zeros(3))

    @staticmethod
    def from_matrix(T: np.ndarray) -> Transform:
        """From a 4x4 homogeneous matrix (its 3x3 block must be a rotation within 1e-6)."""
        M = np.asarray(T, dtype=float)
        if M.shape != (4, 4) or not np.all(np.isfinite(M)):
            raise TransformError(f"expected a finite 4x4 matrix, got shape {M.shape}")
        R = M[:3, :3]
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise TransformError("the 3x3 block is not a rotation matrix")
        return Transform(Rotation.from_matrix(R), M[:3, 3].copy())

    @staticmethod
    def from_quat(q_xyzw: object, t: object = (0.0, 0.0, 0.0)) -> Transform:
        """From a quaternion (x, y, z, w: ROS order) and a translation. A norm off 1 by more than
        :data:`QUAT_TOLERANCE` raises :class:`TransformError`; within it, it is normalised."""
        try:
            q = np.asarray(q_xyzw, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise TransformError(f"quaternion: expected 4 numbers (x, y, z, w), got {q_xyzw!r}") from None
        if q.shape != (4,) or not np.all(np.isfinite(q)):
            raise TransformError(f"quaternion: expected 4 finite numbers (x, y, z, w), got {q_xyzw!r}")
        n = float(np.linalg.norm(q))
        if abs(n - 1.0) > QUAT_TOLERANCE:
            raise TransformError(f"quaternion {q.tolist()} is not a unit quaternion (norm {n:.6f}); "
                                 "expected x, y, z, w with norm 1")
        return Transform(Rotation.from_quat(q / n), _vec3(t, "translation"))

    @staticmethod
    def from_rotvec(rv: object, t: object = (0.0, 0.0, 0.0)) -> Transform:
        """From a rotation vector (axis * angle, radians) and a translation."""
        return Transform(Rotation.from_rotvec(_vec3(rv, "rotation vector")), _vec3(t, "translation"))

    @staticmethod
    def from_rt(R: np.ndarray, t: object) -> Transform:
        """From a 3x3 rotation matrix and a translation."""
        return Transform(Rotation.from_matrix(np.asarray(R, dtype=float)), _vec3(t, "translation"))

    # -- views -------------------------------------------------------------------------------
    @property
    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.rotation.as_matrix()
        T[:3, 3] = self.translation
        return T

    @property
    def R(self) -> np.ndarray:
        return self.rotation.as_matrix()

    @property
    def quat(self) -> np.ndarray:
        """(x, y, z, w), ROS order, w >= 0."""
        q = self.rotation.as_quat()
        return -q if q[3] < 0 else q

    @property
    def rotvec(self) -> np.ndarray:
        return self.rotation.as_rotvec()

    # -- algebra -----------------------------------------------------------------------------
    def inverse(self) -> Transform:
        inv = self.rotation.inv()
        return Transform(inv, -inv.apply(self.translation))

    def __matmul__(self, other: Transform) -> Transform:
        if not isinstance(other, Transform):
            return NotImplemented
        return Transform(self.rotation * other.rotation, self.rotation.apply(other.translation) + self.translation)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Child-frame points (3,) or (N, 3) -> parent frame."""
        p = np.asarray(points, dtype=float)
        return self.rotation.apply(p) + self.translation

    def angle_deg(self) -> float:
        """Rotation angle in degrees."""
        return float(np.degrees(self.rotation.magnitude()))

    def __repr__(self) -> str:
        t = ", ".join(f"{v:.6f}" for v in self.translation)
        q = ", ".join(f"{v:.7f}" for v in self.quat)
        return f"Transform(t=[{t}], q_xyzw=[{q}])"


def interpolate(a: Transform, b: Transform, s: float) -> Transform:
    """Slerp of the rotations and linear interpolation of the translations (s = 0: a, 1: b)."""
    rel = (a.rotation.inv() * b.rotation).as_rotvec()
    rot = a.rotation * Rotation.from_rotvec(s * rel)
    return Transform(rot, (1 - s) * a.translation + s * b.translation)
