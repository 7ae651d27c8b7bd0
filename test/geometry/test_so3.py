import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pascal_calib_ros.geometry.so3 import compose_with_jacobians, left_jacobian, left_jacobian_inverse


@pytest.mark.parametrize("angle", [1e-7, 0.3, 2.0, 3.1])
def test_composition_jacobians_match_central_differences(angle: float) -> None:
    rng = np.random.default_rng(1)
    rv_a = rng.normal(size=(3, 3))
    rv_a *= angle / np.linalg.norm(rv_a, axis=1, keepdims=True)
    rv_b, t_a, t_b = rng.normal(size=(3, 3)) * 0.7, rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    rv, t, Da, Db = compose_with_jacobians(rv_a, t_a, rv_b, t_b)
    R = Rotation.from_rotvec(rv_a) * Rotation.from_rotvec(rv_b)
    assert np.allclose(Rotation.from_rotvec(rv).as_matrix(), R.as_matrix(), atol=1e-12)
    assert np.allclose(t, Rotation.from_rotvec(rv_a).apply(t_b) + t_a, atol=1e-12)

    def f(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        r, tt, _, _ = compose_with_jacobians(a[:, :3], a[:, 3:], b[:, :3], b[:, 3:])
        return np.c_[r, tt]

    A, B = np.c_[rv_a, t_a], np.c_[rv_b, t_b]
    h = 1e-6
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        assert np.allclose((f(A + e, B) - f(A - e, B)) / (2 * h), Da[:, :, k], atol=1e-7)
        assert np.allclose((f(A, B + e) - f(A, B - e)) / (2 * h), Db[:, :, k], atol=1e-7)


def test_left_jacobian_inverse_is_the_inverse_up_to_pi() -> None:
    rng = np.random.default_rng(2)
    for angle in (0.0, 1e-6, 1.0, 3.0, np.pi - 1e-9):
        v = rng.normal(size=3)
        phi = angle * v / np.linalg.norm(v)
        assert np.allclose(left_jacobian(phi) @ left_jacobian_inverse(phi), np.eye(3), atol=1e-9)
