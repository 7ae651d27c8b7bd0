"""The one rigid-transform type: algebra against scipy and 4x4 matrices, quaternion checks."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pascal_calib_ros.errors import PascalCalibError
from pascal_calib_ros.geometry.transform import Transform, TransformError, interpolate


def _random(rng: np.random.Generator) -> Transform:
    return Transform.from_rotvec(rng.normal(size=3), rng.normal(size=3))


def test_compose_inverse_apply_match_matrices() -> None:
    rng = np.random.default_rng(0)
    a, b = _random(rng), _random(rng)
    p = rng.normal(size=(5, 3))
    np.testing.assert_allclose((a @ b).matrix, a.matrix @ b.matrix, atol=1e-12)
    np.testing.assert_allclose(a.inverse().matrix, np.linalg.inv(a.matrix), atol=1e-12)
    np.testing.assert_allclose((a @ b).apply(p), a.apply(b.apply(p)), atol=1e-12)
    np.testing.assert_allclose(a.apply(p), (a.matrix[:3, :3] @ p.T).T + a.matrix[:3, 3], atol=1e-12)
    np.testing.assert_allclose((a @ a.inverse()).matrix, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(Transform.identity().matrix, np.eye(4))


def test_conversions_round_trip_and_ros_quaternion_order() -> None:
    rng = np.random.default_rng(1)
    a = _random(rng)
    np.testing.assert_allclose(Transform.from_matrix(a.matrix).matrix, a.matrix, atol=1e-12)
    np.testing.assert_allclose(Transform.from_quat(a.quat, a.translation).matrix, a.matrix, atol=1e-12)
    np.testing.assert_allclose(Transform.from_rotvec(a.rotvec, a.translation).matrix, a.matrix, atol=1e-12)
    # x, y, z, w: 90 degrees about y
    q = Transform.from_quat([0.0, 0.7071068, 0.0, 0.7071068]).rotation
    np.testing.assert_allclose(q.as_matrix(), Rotation.from_euler("y", 90, degrees=True).as_matrix(), atol=1e-6)
    assert Transform.from_quat([0, 0, 0, -1.0]).quat[3] == 1.0  # w >= 0


def test_non_unit_quaternions_are_refused_and_near_unit_ones_normalised() -> None:
    with pytest.raises(TransformError, match="not a unit quaternion"):
        Transform.from_quat([0.0, 0.0, 0.0, 0.9])
    with pytest.raises(PascalCalibError):
        Transform.from_quat([0.0, 0.0, 1.0])
    with pytest.raises(ValueError):
        Transform.from_quat([0.0, 0.0, 0.0, float("nan")])
    t = Transform.from_quat([0.0, 0.0, 0.0, 1.0005])
    np.testing.assert_allclose(t.quat, [0, 0, 0, 1])
    with pytest.raises(TransformError):
        Transform.from_matrix(np.diag([1.0, 1.0, -1.0, 1.0]))


def test_interpolate_is_slerp_and_lerp() -> None:
    a = Transform.from_rotvec([0, 0, 0.2], [0, 0, 0])
    b = Transform.from_rotvec([0, 0, 1.0], [1, 2, 3])
    m = interpolate(a, b, 0.5)
    np.testing.assert_allclose(m.rotvec, [0, 0, 0.6], atol=1e-12)
    np.testing.assert_allclose(m.translation, [0.5, 1, 1.5])
    np.testing.assert_allclose(interpolate(a, b, 0).matrix, a.matrix, atol=1e-12)
    np.testing.assert_allclose(interpolate(a, b, 1).matrix, b.matrix, atol=1e-12)
