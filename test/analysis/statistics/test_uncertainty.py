"""Honest uncertainties: correlation factors of residual sequences, the sandwich covariance, and
mrcal's projection uncertainty checked against cases whose answer is known in closed form."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pascal_calib_ros.analysis.statistics.assessment import assess
from pascal_calib_ros.analysis.statistics.compare import projection_difference
from pascal_calib_ros.analysis.statistics.uncertainty import (
    projection_uncertainty_of,
    rotation_displacements,
    rotation_free_difference_variance,
)
from pascal_calib_ros.calibrate.intrinsic import pipeline
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.calibrate.solver.covariance import lag_factor
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.report.text import projection_line
from pascal_calib_ros.targets import Target


def test_lag_factor_of_white_and_correlated_sequences() -> None:
    rng = np.random.default_rng(1)
    white = [rng.normal(size=500) for _ in range(40)]
    assert lag_factor(white, circular=True) == pytest.approx(1.0, abs=0.1)
    # moving average of two neighbours: rho_1 = 1/2, the rest 0 -> kappa = 2
    ma = []
    for _ in range(40):
        e = rng.normal(size=501)
        ma.append(e[:-1] + e[1:])
    assert lag_factor(ma, circular=False) == pytest.approx(2.0, abs=0.15)
    # three neighbours: rho_1 = 2/3, rho_2 = 1/3 -> kappa = 3
    ma3 = []
    for _ in range(40):
        e = rng.normal(size=502)
        ma3.append(e[:-2] + e[1:-1] + e[2:])
    assert lag_factor(ma3, circular=False) == pytest.approx(3.0, abs=0.25)


@pytest.fixture(scope="module")
def ring_result(ring_target: Target, ring_session: tuple[Camera, list[np.ndarray], list[Detection]]):
    _, _, dets = ring_session
    return assess(calibrate(dets, ring_target))


def test_sigmas_come_from_the_sandwich_covariance(ring_result) -> None:
    res = ring_result
    assert res.projection is not None
    assert res.projection.distance > 0.1  # the median target distance
    assert all(res.result.std[k] > 0 for k in ("fx", "fy", "cx", "cy"))
    s = res.projection_summary()
    assert s is not None and 0 < s["median_px"] <= s["worst_px"] < 1.0
    assert "projection sigma" in projection_line(res) and "observed field" in projection_line(res)


def test_projection_uncertainty_of_known_covariances(ring_target: Target, ring_session,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A covariance on cx alone moves every pixel by the same amount (sigma = std(cx)); one on fx
    alone moves a pixel by (u - cx) / fx std(fx), nothing at the principal point; none: zero."""
    _, _, dets = ring_session
    captured = {}
    original = pipeline.refine

    def spy(*a, **k):  # records the refinement behind the calibration (the last one)
        captured["r"] = original(*a, **k)
        return captured["r"]

    monkeypatch.setattr(pipeline, "refine", spy)
    calibrate(dets, ring_target)
    r = captured["r"]
    n = len(r.x)
    free = r.problem.free
    for name, idx in (("cx", 2), ("fx", 0)):
        cov = np.zeros((n, n))
        k = free.index(idx)
        cov[k, k] = 0.04  # std 0.2
        pu = projection_uncertainty_of(replace(r, covariance=cov), ImageSize(800, 600), 0.5)
        ok = np.isfinite(pu.sigma)
        assert ok.mean() > 0.9
        if name == "cx":
            np.testing.assert_allclose(pu.sigma[ok], 0.2, rtol=1e-3)
        else:
            K = r.K
            expect = 0.2 * np.abs(pu.pixels[ok, 0] - K[0, 2]) / K[0, 0]
            # distortion makes x/z differ a little from (u - cx) / fx away from the centre
            near = np.hypot(pu.pixels[ok, 0] - K[0, 2], pu.pixels[ok, 1] - K[1, 2]) < 150
            np.testing.assert_allclose(pu.sigma[ok][near], expect[near], atol=2e-3)
    zero = projection_uncertainty_of(replace(r, covariance=np.zeros((n, n))), ImageSize(800, 600), 0.5)
    assert np.nanmax(zero.sigma) == 0.0


def test_rotation_free_difference_removes_what_a_rotation_absorbs(ring_target: Target, ring_session,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """At infinity a principal-point error is nearly a rotation of the camera (the difference's
    fitted rotation removes most of it); a focal-length error is not (it stays)."""
    _, _, dets = ring_session
    captured = {}
    original = pipeline.refine

    def spy(*a, **k):
        captured["r"] = original(*a, **k)
        return captured["r"]

    monkeypatch.setattr(pipeline, "refine", spy)
    res = calibrate(dets, ring_target)
    r = captured["r"]
    cam = res.camera()
    us, vs = np.meshgrid(np.arange(40, 800, 40.0), np.arange(30, 600, 40.0))
    rays = cam.unproject(np.stack([us.ravel(), vs.ravel()], 1))
    H = rotation_displacements(cam, rays)
    n = len(r.x)
    for idx, most_removed in ((2, True), (0, False)):
        cov = np.zeros((n, n))
        k = r.problem.free.index(idx)
        cov[k, k] = 0.04  # std 0.2 px
        var = rotation_free_difference_variance(r.camera_of, r.view_poses_of, r.x, cov, rays, H)
        rms = float(np.sqrt(np.mean(var)))
        if most_removed:  # what the diff of a camera with cx moved by 0.2 px leaves, directly
            K2 = cam.K.copy()
            K2[0, 2] += 0.2
            direct = projection_difference(cam, Camera(K2, cam.D, cam.width, cam.height, cam.model), step=40.0)
            assert rms < 0.1 * 0.2 and rms == pytest.approx(direct.rms, rel=0.1), (rms, direct.rms)
        else:
            plain = 0.2 * np.sqrt(np.mean(((us.ravel() - cam.K[0, 2]) / cam.K[0, 0]) ** 2))
            assert 0.5 * plain < rms <= 1.05 * plain, (rms, plain)


@pytest.mark.parametrize("loss_scale", [0.3, np.inf])
def test_robust_sigma_covers_the_spread_as_least_squares_does(loss_scale: float) -> None:
    """Monte Carlo (issue 22): white corner noise of 0.2 px, 40 draws on the same poses. With the
    soft-L1 loss at 0.3 px the M-estimator's sandwich (psi' in the bread, psi^2 in the meat) gives
    the spread of the estimates as least squares does; the IRLS weights in both gave 0.77 of it."""
    from pascal_calib_ros.calibrate.solver.observations import ViewData
    from pascal_calib_ros.calibrate.solver.refine import refine
    from pascal_calib_ros.geometry.camera import rodrigues

    cam = Camera.from_params(600.0, 610.0, 322.0, 238.0, 0.0, [-0.2, 0.05, 0.001, -0.002, 0.01], 640, 480)
    board = np.array([(0.025 * i, 0.025 * j) for j in range(7) for i in range(10)]) - [0.1125, 0.075]
    rng = np.random.default_rng(1)
    poses = [(np.r_[rng.uniform(-0.6, 0.6, 2), rng.uniform(-0.3, 0.3)],
              np.r_[rng.uniform(-0.08, 0.08), rng.uniform(-0.06, 0.06), rng.uniform(0.45, 0.6)]) for _ in range(8)]
    exact = [cam.project(np.c_[board, np.zeros(len(board))] @ rodrigues(rv).T + t) for rv, t in poses]
    est, sig = [], []
    for draw in range(40):
        noise = np.random.default_rng(100 + draw)
        views = []
        for q in exact:
            v = ViewData(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, int))
            v.corners, v.corner_obj = q + noise.normal(0, 0.2, q.shape), board
            views.append(v)
        res = refine(views, cam.K * [[1.01, 1, 1], [1, 0.99, 1], [1, 1, 1]], np.zeros(5),
                     [np.r_[rv, t] for rv, t in poses], 6, use_offsets=False, loss_scale=loss_scale)
        est.append([res.K[0, 0], res.K[0, 2], res.K[1, 2]])
        sig.append([res.std["fx"], res.std["cx"], res.std["cy"]])
    ratio = np.std(est, axis=0, ddof=1) / np.mean(sig, axis=0)
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio  # 40 draws: the spread is known to about 11 %
