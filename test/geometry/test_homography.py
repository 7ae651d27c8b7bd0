import numpy as np
import pytest

from pascal_calib_ros.geometry.homography import fit_homography


def test_exact_homography_in_double_precision() -> None:
    H = np.array([[620.0, 12.0, 400.0], [-8.0, 610.0, 300.0], [0.02, -0.03, 1.0]])
    src = np.stack(np.meshgrid(np.linspace(-1, 1, 9), np.linspace(-0.7, 0.7, 6)), -1).reshape(-1, 2)
    p = np.c_[src, np.ones(len(src))] @ H.T
    est = fit_homography(src, p[:, :2] / p[:, 2:3])
    assert np.allclose(est, H, rtol=1e-10, atol=1e-9)


def test_too_few_points() -> None:
    with pytest.raises(ValueError):
        fit_homography(np.zeros((3, 2)), np.zeros((3, 2)))
