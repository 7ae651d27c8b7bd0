import numpy as np
from scipy.special import ndtr

from pascal_calib_ros.detect.edges import EdgeError, fit_step_profiles, refine_edge
from pascal_calib_ros.geometry.conic import Ellipse, sampson_distance


def test_step_fit_recovers_position_and_width() -> None:
    s = np.arange(-6, 6.01, 0.5)
    rng = np.random.default_rng(0)
    s0 = rng.uniform(-1, 1, 200)
    w = rng.uniform(0.6, 2.0, 200)
    prof = 60 + 0.5 * s[None, :] + 150 * ndtr((s[None, :] - s0[:, None]) / w[:, None])
    est_s0, est_w, est_c, _rms = fit_step_profiles(prof + rng.normal(0, 0.5, prof.shape), s)
    assert np.sqrt(np.mean((est_s0 - s0) ** 2)) < 0.02
    assert np.sqrt(np.mean((est_w - w) ** 2)) < 0.05
    assert np.allclose(est_c, 150, rtol=0.05)


def _blurred_disc(r: float, sigma: float, size: int = 200) -> np.ndarray:
    """Dark disc on white, Gaussian-blurred analytically in the radial direction (supersampled)."""
    import cv2

    ss = 8
    yy, xx = np.mgrid[0:size * ss, 0:size * ss] / ss + (0.5 / ss - 0.5)
    disc = (np.hypot(xx - 100.3, yy - 99.6) < r).astype(np.float64)
    img = cv2.resize(disc, (size, size), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), sigma)
    return (220 - 170 * img).astype(np.float32)


def test_curvature_correction_removes_the_blur_bias_of_a_small_circle() -> None:
    r, sigma = 12.0, 1.8
    img = _blurred_disc(r, sigma)
    truth = Ellipse(100.3, 99.6, r, r, 0).to_conic()
    start = Ellipse(100.0, 100.0, r + 1, r + 1, 0).to_conic()
    with_corr = refine_edge(img, start, curvature_correction=True)
    without = refine_edge(img, start, curvature_correction=False)
    bias_with = float(np.mean(sampson_distance(truth, with_corr.points)))
    bias_without = float(np.mean(sampson_distance(truth, without.points)))
    assert bias_without < -0.08  # mid-level on the concave side by ~ sigma^2 / (2 r) = 0.135 px
    assert abs(bias_with) < 0.3 * abs(bias_without)


def test_flat_image_has_no_edge() -> None:
    img = np.full((100, 100), 128, np.float32)
    try:
        refine_edge(img, Ellipse(50, 50, 20, 15, 0).to_conic())
    except EdgeError as e:
        assert "edge" in str(e)
    else:
        raise AssertionError("no edge must be found in a flat image")


def test_edge_near_border_is_refused() -> None:
    img = _blurred_disc(12.0, 1.0)
    try:
        refine_edge(img, Ellipse(5, 100, 12, 12, 0).to_conic())
    except EdgeError as e:
        assert "border" in str(e)
    else:
        raise AssertionError("an edge at the border must be refused")
