import numpy as np
import pytest
from conftest import homography, random_plane_poses

from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.iac import DegenerateViewsError, iac_from_circular_points, k_from_omega

K = np.array([[800.0, 0.0, 410.0], [0.0, 805.0, 295.0], [0.0, 0.0, 1.0]])


def _i(rv: np.ndarray, t: np.ndarray) -> np.ndarray:
    i = homography(K, rv, t) @ np.array([1, 1j, 0])
    return i / i[2] if abs(i[2]) > 1e-9 * np.abs(i).max() else i


def test_three_views_give_K_and_a_healthy_ratio() -> None:
    pts = [_i(rv, t) for rv, t in random_plane_poses(3, 2)]
    assert np.allclose(iac_from_circular_points(pts, ImageSize(800, 600)).K, K, rtol=1e-9)
    pts = [_i(rv, t) for rv, t in random_plane_poses(8, 2)]
    sol = iac_from_circular_points(pts, ImageSize(800, 600))
    assert np.allclose(sol.K, K, rtol=1e-9)
    assert sol.degeneracy_ratio > 0.05 and not sol.warning


def test_zero_skew_needs_two_views_only() -> None:
    pts = [_i(rv, t) for rv, t in random_plane_poses(2, 3)]
    with pytest.raises(DegenerateViewsError):
        iac_from_circular_points(pts, ImageSize(800, 600))
    assert np.allclose(iac_from_circular_points(pts, ImageSize(800, 600), zero_skew=True).K, K, rtol=1e-9)


def test_two_views_are_refused_with_advice() -> None:
    pts = [_i(rv, t) for rv, t in random_plane_poses(2, 4)]
    with pytest.raises(DegenerateViewsError, match="at least 3 views"):
        iac_from_circular_points(pts, ImageSize(800, 600))


def test_parallel_planes_are_degenerate() -> None:
    rv = np.array([0.3, 0.2, 0.1])
    pts = [_i(rv, np.array([x, y, z])) for x, y, z in ((0, 0, 1), (0.1, 0, 1.2), (0, 0.1, 0.9), (0.05, 0.05, 1.5))]
    with pytest.raises(DegenerateViewsError, match="parallel"):
        iac_from_circular_points(pts, ImageSize(800, 600))


def test_fronto_parallel_views_are_degenerate() -> None:
    pts = [_i(np.array([0.0, 0.0, a]), np.array([0.0, 0.0, 1.0])) for a in (0.0, 0.5, 1.0, 2.0)]
    with pytest.raises(DegenerateViewsError):
        iac_from_circular_points(pts, ImageSize(800, 600))


def test_not_positive_definite_is_rejected_not_clipped() -> None:
    with pytest.raises(DegenerateViewsError, match="positive definite"):
        k_from_omega(np.diag([1.0, -1.0, 1.0]))
