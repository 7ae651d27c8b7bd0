import numpy as np

from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import (
    Camera,
    distort,
    model_error,
    rodrigues,
    rotation_to_rvec,
    undistort,
)


def test_undistort_inverts_distort_under_strong_barrel() -> None:
    D = np.array([-0.45, 0.2, 0.001, -0.002, -0.03])
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.6, 0.6, size=(500, 2))
    back = undistort(distort(xy, D), D)
    assert np.max(np.abs(back - xy)) < 1e-10


def test_project_matches_opencv() -> None:
    import cv2

    cam = Camera.from_params(700, 710, 320, 240, dist=[-0.2, 0.05, 0.001, 0.002, 0.01])
    X = np.random.default_rng(1).uniform([-0.3, -0.2, 1.0], [0.3, 0.2, 2.0], size=(50, 3))
    ref, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, cam.D)
    assert np.max(np.abs(cam.project(X) - ref.reshape(-1, 2))) < 1e-9


def test_rodrigues_round_trip() -> None:
    for rv in (np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.0, 0.0]), np.array([3.0, 0.1, 0.0])):
        assert np.allclose(rotation_to_rvec(rodrigues(rv)), rv, atol=1e-9)


def test_model_error_is_zero_for_identical_and_positive_otherwise() -> None:
    a = Camera.from_params(800, 800, 400, 300, dist=[-0.2, 0, 0, 0, 0])
    assert model_error(a, a, ImageSize(800, 600)) < 1e-9
    b = Camera.from_params(800, 800, 401, 300, dist=[-0.2, 0, 0, 0, 0])
    assert 0.9 < model_error(a, b, ImageSize(800, 600)) < 1.1


def test_calibration_errors() -> None:
    from pascal_calib_ros.geometry.camera import calibration_errors

    truth = Camera.from_params(800, 800, 400, 300, width=800, height=600)
    K = truth.K.copy()
    K[0, 0] *= 1.001
    K[0, 2] += 3
    K[1, 2] -= 4
    e = calibration_errors(truth, K, np.zeros(5))
    assert abs(e["fx_err_pct"] - 0.1) < 1e-9 and e["fy_err_pct"] == 0
    assert e["cx_err_px"] == 3 and e["cy_err_px"] == -4 and abs(e["pp_err_px"] - 5) < 1e-12
    assert e["model_err_px"] > 0
