"""Residual statistics and the model-bias verdict (analysis/statistics/residual_stats.py) on synthetic residuals."""

import numpy as np

from pascal_calib_ros.analysis.statistics.residual_stats import (
    REGIONAL_FLOOR_PX,
    contour_normals,
    model_bias,
    radial,
    region_grid,
    regional,
    residual_samples,
    views_per_region,
)
from pascal_calib_ros.geometry import ImageSize

W, H = 800, 600


def _circles(rng: np.random.Generator, n_views: int = 10, per_view: int = 30, n_pts: int = 60
             ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Circles of radius 12 px spread over the image: per view, points in contour order and ids."""
    pts, ids = [], []
    t = np.linspace(0, 2 * np.pi, n_pts, endpoint=False)
    for _ in range(n_views):
        c = rng.uniform([40, 40], [W - 40, H - 40], (per_view, 2))
        pts.append(np.concatenate([ci + 12 * np.stack([np.cos(t), np.sin(t)], 1) for ci in c]))
        ids.append(np.repeat(np.arange(per_view), n_pts))
    return pts, ids


def _verdict(pts: list[np.ndarray], ids: list[np.ndarray], res: list[np.ndarray], kappa: float = 1.0):
    s = residual_samples(pts, res, ids, kappa=(kappa, 1.0))
    return model_bias(regional(s, ImageSize(W, H)), radial(s, (W / 2, H / 2)), ImageSize(W, H), "plumb_bob")


def test_contour_normals_point_outwards_along_the_radius() -> None:
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    p = np.array([100.0, 50.0]) + 7 * np.stack([np.cos(t), np.sin(t)], 1)
    n = contour_normals(p, np.zeros(40, int))
    assert np.allclose(n, np.stack([np.cos(t), np.sin(t)], 1), atol=1e-9)
    # the reverse order gives the same outward normals
    assert np.allclose(contour_normals(p[::-1], np.zeros(40, int)), n[::-1], atol=1e-9)


def test_noise_is_not_a_bias_and_a_radial_pattern_is() -> None:
    rng = np.random.default_rng(3)
    pts, ids = _circles(rng)
    noise = [rng.normal(0, 0.08, len(p)) for p in pts]
    clean = _verdict(pts, ids, noise)
    assert not clean.detected and clean.hint == ""
    # a radial distortion the model misses: observed farther out than predicted, growing with radius^3
    bias = []
    for p, r in zip(pts, noise, strict=True):
        d = p - [W / 2, H / 2]
        rad = np.hypot(d[:, 0], d[:, 1])
        n = contour_normals(p, np.repeat(np.arange(len(p) // 60), 60))
        radial_px = 0.05 * (rad / 500) ** 3
        bias.append(r + radial_px * np.sum(n * d / rad[:, None], 1))
    v = _verdict(pts, ids, bias)
    assert v.detected and v.radial_significant > 0
    assert "rational_polynomial" in v.hint and "--target-shape" in v.hint
    rad_prof = radial(residual_samples(pts, bias, ids), (W / 2, H / 2))
    assert rad_prof.mean[-1] > 0.015 > 0.005 > abs(rad_prof.mean[0])


def test_a_bias_below_the_floor_or_hidden_in_correlated_noise_is_not_called() -> None:
    rng = np.random.default_rng(5)
    pts, ids = _circles(rng)
    # a constant shift of 0.4 x floor in one region: statistically real with this many points,
    # but below the floor
    shift = []
    for p in pts:
        r = rng.normal(0, 0.05, len(p))
        n = contour_normals(p, np.repeat(np.arange(len(p) // 60), 60))
        inside = (p[:, 0] < W / 8) & (p[:, 1] < H / 6)
        shift.append(r + inside * 0.4 * REGIONAL_FLOOR_PX * n[:, 0])
    assert not _verdict(pts, ids, shift).detected
    # the same shift at 3x the floor is called, and the hint names the region's position
    strong = []
    for p in pts:
        n = contour_normals(p, np.repeat(np.arange(len(p) // 60), 60))
        inside = (p[:, 0] < W / 8) & (p[:, 1] < H / 6)
        strong.append(rng.normal(0, 0.05, len(p)) + inside * 3 * REGIONAL_FLOOR_PX * n[:, 0])
    v = _verdict(pts, ids, strong)
    assert v.detected and v.regional_significant >= 1 and v.max_regional_at == (W / 16, H / 12)
    # smooth noise correlated along each edge (a moving average over 9 points) is still noise:
    # with its correlation factor the verdict stays silent
    smooth = [np.convolve(rng.normal(0, 0.15, len(p)), np.ones(9) / 3, "same") for p in pts]
    assert not _verdict(pts, ids, smooth, kappa=9.0).detected


def test_regional_mean_and_counts() -> None:
    pts = [np.array([[10.0, 10.0], [20.0, 20.0], [790.0, 590.0]])]
    vec = residual_samples(pts, [np.zeros(3)], [np.zeros(3, int)], [np.zeros((0, 2))], [np.zeros((0, 2))])
    reg = regional(vec, ImageSize(W, H))
    assert reg.grid == region_grid(ImageSize(W, H)) == (6, 8)
    assert reg.count[0] == 2 and reg.count[-1] == 1 and reg.count.sum() == 3
    counts = views_per_region([pts[0], pts[0][:1]], ImageSize(W, H))
    assert counts[0, 0] == 2 and counts[-1, -1] == 1 and counts.sum() == 3


def test_corner_residuals_join_the_samples() -> None:
    corners = [np.array([[100.0, 100.0], [200.0, 100.0]])]
    res = [np.array([[0.1, 0.0], [0.0, -0.1]])]
    s = residual_samples([np.zeros((0, 2))], [np.zeros(0)], [np.zeros(0, int)], corners, res, kappa=(1.0, 2.0))
    assert s.is_corner.all() and np.allclose(s.vectors, res[0]) and np.allclose(s.kappa, 2.0)
    # corners without residuals (unknown) are left out rather than misaligned
    s2 = residual_samples([np.zeros((0, 2))], [np.zeros(0)], [np.zeros(0, int)], corners, [])
    assert len(s2.points) == 0
