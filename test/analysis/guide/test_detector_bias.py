"""The detector's bias in the arm's prediction (analysis/guide/detector_bias.py)."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.arm_guidance import (
    TrustRegion,
    arm_candidates,
    arm_model,
    chain_rows,
    hand_eye_sigmas,
)
from pascal_calib_ros.analysis.guide.detector_bias import DETECTOR_BIAS, BiasedPredictor, DetectorBias, semi_axes_px
from pascal_calib_ros.analysis.guide.guidance import Linearisation, ViewPredictor, semi_minor_px
from pascal_calib_ros.analysis.guide.view_ranking import predict_poses
from pascal_calib_ros.calibrate.handeye.options import HandEyeOptions
from pascal_calib_ros.calibrate.handeye.session import calibrate_hand_eye
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.solver.observations import ViewData
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import resolve_target

W, H = 640, 480
NO_BIAS = DetectorBias(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def arm_case():  # type: ignore[no-untyped-def]
    target = resolve_target("ring_grid_a4")
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=5, width=W, height=H, seed=3,
                                             systematic_mm=0.0))
    dets = [detect_target(img, target) for img in s.images[target.name]]
    h = calibrate_hand_eye(dets, list(s.robot_poses), target, "eye_in_hand", he=HandEyeOptions(jackknife_groups=0))
    used = [k for k, v in enumerate(h.per_view) if v.used]
    poses = [s.robot_poses[k] for k in used]
    noise = ViewPredictor(Linearisation.of_refinement(h.calibration.refinement), ImageSize(W, H)).noise
    return target, h, poses, noise


def test_the_bias_shrinks_steeply_with_the_circles_size() -> None:
    """sigma = sigma_8 (axis / 8 px)^p, the rotation's of the semi-major axis, the translation's
    of the semi-minor one, both clipped to the measured range."""
    b = np.array([4.0, 4.5, 8.0, 10.0, 20.0])
    s = DETECTOR_BIAS.sigmas(b, b)
    assert s.shape == (5, 6)
    np.testing.assert_allclose(np.degrees(s[2, :3]), DETECTOR_BIAS.rotation_deg)
    np.testing.assert_allclose(s[2, 5] * 1000, DETECTOR_BIAS.along_mm)
    assert np.all(np.diff(s[1:4], axis=0) < 0)  # smaller circles, more bias
    np.testing.assert_allclose(s[0], s[1])  # clipped below
    np.testing.assert_allclose(s[4], DETECTOR_BIAS.sigmas(np.array([14.0]), np.array([14.0]))[0])  # and above
    tilted = DETECTOR_BIAS.sigmas(np.array([6.0]), np.array([8.0]))[0]  # a tilt shortens b only
    np.testing.assert_allclose(tilted[:3], s[2, :3])
    assert np.all(tilted[3:] > s[2, 3:])


def test_semi_axes_of_an_ellipse() -> None:
    """The medians of the circles' semi-axes from their edge points: 8 and 5 px ellipses."""
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    ell = np.c_[8 * np.cos(t), 5 * np.sin(t)] @ np.array([[0.8, 0.6], [-0.6, 0.8]])
    pts = np.concatenate([ell + c for c in ((100.0, 100.0), (150.0, 100.0), (100.0, 150.0))])
    n = len(pts)
    view = ViewData(pts, np.zeros((n, 2)), np.ones(n), np.ones(n), np.repeat([0, 1, 2], 64))
    b, a = semi_axes_px(view)
    assert b == pytest.approx(5.0, rel=1e-6) and a == pytest.approx(8.0, rel=1e-6)
    assert b == pytest.approx(semi_minor_px(view), rel=1e-9)


def _candidates(target, model, poses, k=6):  # type: ignore[no-untyped-def]
    cands, tools = arm_candidates(model, target, TrustRegion(tuple(poses)))
    assert len(cands) >= k
    idx = list(range(0, len(cands), max(len(cands) // k, 1)))[:k]
    return [cands[i][1] for i in idx], [tools[i] for i in idx]


def test_without_bias_the_biased_predictor_is_the_plain_one(arm_case) -> None:  # type: ignore[no-untyped-def]
    """Zero sigmas: the same covariance now and after each candidate as
    :class:`.guidance.ViewPredictor` (the update's algebra is the same)."""
    target, h, poses, noise = arm_case
    model = arm_model(h, poses, target, noise, ImageSize(W, H), bias=NO_BIAS)
    assert isinstance(model.predictor, BiasedPredictor)
    plain = ViewPredictor(model.predictor.lin, ImageSize(W, H))
    np.testing.assert_allclose(model.predictor.cov_now, plain.cov_now, rtol=1e-8, atol=1e-20)
    cams, tools = _candidates(target, model, poses)
    chain = chain_rows(model, tools)
    a = predict_poses(model.predictor, target, cams, CalibrationOptions(), chain=chain)
    b = predict_poses(plain, target, cams, CalibrationOptions(), chain=chain)
    np.testing.assert_allclose(a.readout_cov, b.readout_cov, rtol=1e-6, atol=1e-18)


def test_the_bias_adds_to_the_hand_eye_sigma_now_and_after_a_view(arm_case) -> None:  # type: ignore[no-untyped-def]
    """The bias is a variance on top of the noise's: X's predicted sigmas grow, now and after
    every candidate, with the views' biases independent (rho 0) or correlated (rho 0.6; the
    common share may then cancel some of the rest: no order between the two)."""
    target, h, poses, noise = arm_case
    base = arm_model(h, poses, target, noise, ImageSize(W, H), bias=NO_BIAS)
    cams, tools = _candidates(target, base, poses)
    figures = []
    for b in (NO_BIAS, DetectorBias(rho=0.0), DetectorBias(rho=0.6)):
        m = arm_model(h, poses, target, noise, ImageSize(W, H), bias=b)
        p = predict_poses(m.predictor, target, cams, CalibrationOptions(), chain=chain_rows(m, tools))
        figures.append((hand_eye_sigmas(m, m.predictor.cov_now), hand_eye_sigmas(m, p.readout_cov)))
    (n0, c0), (n1, c1), (n2, c2) = figures
    for k in (0, 1):  # rotation, translation
        assert n1[k] > n0[k] and np.all(c1[k] > c0[k])
        assert n2[k] > n0[k] and np.all(c2[k] > c0[k])
        assert n2[k] != pytest.approx(n1[k], rel=1e-3)


def test_the_model_takes_kappa_out_of_the_image_rows_only_when_asked(arm_case) -> None:  # type: ignore[no-untyped-def]
    """Without ``keep_kappa`` the image rows' variances are divided by the refinement's kappa
    (what reaches X) and the ranking's projection factor is kappa; the shipped model keeps kappa
    in, has no bias and a factor of 1."""
    target, h, poses, noise = arm_case
    kappa = h.calibration.refinement.kappa[0]
    assert kappa > 1.2
    honest = arm_model(h, poses, target, noise, ImageSize(W, H), bias=DETECTOR_BIAS, keep_kappa=False)
    shipped = arm_model(h, poses, target, noise, ImageSize(W, H))
    assert honest.kappa == pytest.approx(kappa) and shipped.kappa == 1.0
    assert isinstance(honest.predictor, BiasedPredictor) and not isinstance(shipped.predictor, BiasedPredictor)
    n_edge = shipped.problem.n_edge
    np.testing.assert_allclose(honest.predictor.lin.var[:n_edge] * kappa, shipped.predictor.lin.var[:n_edge])
