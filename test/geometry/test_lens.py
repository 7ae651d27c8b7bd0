"""Lens models (geometry/lens.py): OpenCV's conventions, exact Jacobians, rays beyond 90 degrees."""

import cv2
import numpy as np
import pytest

from pascal_calib_ros.geometry.camera import Camera, project_with_jacobians, rectified_projection
from pascal_calib_ros.geometry.lens import EQUIDISTANT, PLUMB_BOB, RATIONAL, lens_model, model_for_coefficients

K = np.array([[500.0, 0.0, 320.0], [0.0, 505.0, 240.0], [0.0, 0.0, 1.0]])
D_RATIONAL = np.array([0.3, -0.1, 0.001, -0.002, 0.02, 0.25, -0.05, 0.01])
D_FISHEYE = np.array([0.02, -0.01, 0.003, -0.001])
CAMERAS = {
    "plumb_bob": Camera(K, D_RATIONAL[:5], 640, 480, "plumb_bob"),
    "rational_polynomial": Camera(K, D_RATIONAL, 640, 480, "rational_polynomial"),
    "equidistant": Camera(K, D_FISHEYE, 640, 480, "equidistant"),
}


def _points(rng: np.random.Generator, n: int = 60, behind: bool = False) -> np.ndarray:
    X = rng.uniform([-0.5, -0.4, 0.6], [0.5, 0.4, 1.5], (n, 3))
    if behind:  # rays from 0 to about 130 degrees off the axis
        X[:, 2] = rng.uniform(-0.5, 1.5, n)
    return X


def test_rational_and_fisheye_project_as_opencv() -> None:
    X = _points(np.random.default_rng(0))
    ref, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K, D_RATIONAL)
    assert np.abs(CAMERAS["rational_polynomial"].project(X) - ref.reshape(-1, 2)).max() < 1e-9
    ref, _ = cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D_FISHEYE)
    assert np.abs(CAMERAS["equidistant"].project(X) - ref.reshape(-1, 2)).max() < 1e-9


def test_fisheye_uses_the_rays_own_angle_beyond_90_degrees() -> None:
    """OpenCV's atan(r) of x/z mirrors a ray behind the image plane through the centre; the ray's
    angle keeps it on its own side of the image."""
    cam = CAMERAS["equidistant"]
    ahead, sideways = np.array([[1.0, 0.0, 0.2]]), np.array([[1.0, 0.0, -0.2]])
    u_ahead, u_side = cam.project(ahead)[0, 0], cam.project(sideways)[0, 0]
    assert u_side > u_ahead > K[0, 2]  # farther out, same side
    theta = np.arctan2(1.0, -0.2)
    td = theta * (1 + D_FISHEYE @ theta ** np.array([2, 4, 6, 8]))
    assert abs(u_side - (K[0, 0] * td + K[0, 2])) < 1e-9


@pytest.mark.parametrize("model", list(CAMERAS))
def test_unproject_inverts_project(model: str) -> None:
    cam = CAMERAS[model]
    X = _points(np.random.default_rng(1), behind=cam.lens.wide)
    if cam.lens.wide:
        theta = np.arctan2(np.hypot(X[:, 0], X[:, 1]), X[:, 2])
        X = X[theta < cam.lens.max_angle(cam.D) - 0.01]
        assert np.any(X[:, 2] < 0)  # some rays beyond 90 degrees remain
    rays = cam.unproject(cam.project(X))
    assert np.abs(rays - X / np.linalg.norm(X, axis=1, keepdims=True)).max() < 1e-9


def test_unproject_is_nan_beyond_the_monotonic_range() -> None:
    cam = Camera(K, np.array([-0.3, 0.0, 0.0, 0.0]), 640, 480, "equidistant")  # folds at ~63 degrees
    t_max = cam.lens.max_angle(cam.D)
    assert 0.9 < t_max < 1.2
    far = np.array([[K[0, 2] + 2000.0, K[1, 2]]])
    assert np.all(np.isnan(cam.unproject(far)))


@pytest.mark.parametrize("model", list(CAMERAS))
def test_analytic_jacobians_match_central_differences(model: str) -> None:
    cam = CAMERAS[model]
    X = _points(np.random.default_rng(2), 30, behind=cam.lens.wide)
    q, dX, dI = project_with_jacobians(X, cam.K, cam.D, cam.lens)
    assert np.abs(q - cam.project(X)).max() < 1e-9
    h = 1e-6
    num = np.stack([(cam.project(X + e) - cam.project(X - e)) / (2 * h) for e in np.eye(3) * h], -1)
    assert np.abs(num - dX).max() < 1e-6 * np.abs(dX).max()
    p = np.r_[cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2], cam.K[0, 1], cam.D]

    def proj(v: np.ndarray) -> np.ndarray:
        Kv = np.array([[v[0], v[4], v[2]], [0, v[1], v[3]], [0, 0, 1.0]])
        return Camera(Kv, v[5:], 640, 480, model).project(X)

    numI = np.stack([(proj(p + e) - proj(p - e)) / (2 * h) for e in np.eye(len(p)) * h], -1)
    assert np.abs(numI - dI).max() < 1e-6 * np.abs(dI).max()


def test_model_names_and_coefficient_counts() -> None:
    assert lens_model("plumb_bob_k3_fixed") is PLUMB_BOB and lens_model("equidistant") is EQUIDISTANT
    assert model_for_coefficients(np.zeros(8)) is RATIONAL
    with pytest.raises(ValueError, match="unknown distortion model"):
        lens_model("fisheye")
    with pytest.raises(ValueError, match="4 distortion coefficients"):
        Camera(K, np.zeros(5), 640, 480, "equidistant")


def test_rectified_projection() -> None:
    pin = CAMERAS["rational_polynomial"]
    assert np.array_equal(rectified_projection(pin)[:, :3], pin.K)
    fish = Camera(np.array([[190.0, 0, 320], [0, 190.0, 240], [0, 0, 1]]), D_FISHEYE, 640, 480, "equidistant")
    P = rectified_projection(fish)
    # the pinhole view spans +-60 degrees horizontally (the fisheye sees more than that)
    assert abs(np.degrees(np.arctan(319 / P[0, 0])) - 60) < 1e-9  # nearer border: 639 - 320
    assert P[0, 2] == 320 and P[1, 2] == 240 and np.all(P[:, 3] == 0)


def test_polynomial_unproject_is_nan_beyond_the_fold() -> None:
    """A rational lens that folds at ~57 degrees: a pixel beyond the fold has no ray on the
    growing branch (Newton alone lands on the far branch, which projects to the same pixel)."""
    D = np.array([0.6, -0.05, 0.0005, -0.0003, 0.0, 0.95, 0.1, 0.0])
    cam = Camera(np.array([[500.0, 0, 512], [0, 500, 384], [0, 0, 1]]), D, 1024, 768, "rational_polynomial")
    assert 0.9 < cam.lens.max_angle(D) < 1.1
    assert np.all(np.isnan(cam.unproject(np.array([[1023.0, 377.0]]))))
    inside = cam.project(np.array([[0.3, 0.1, 1.0]]))
    assert np.all(np.isfinite(cam.unproject(inside)))
