"""The arm's candidates and ranking (analysis/guide/arm_guidance.py) on a small simulated eye-in-hand session."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.arm_guidance import (
    ArmGoals,
    TrustRegion,
    arm_candidates,
    arm_model,
    suggest_arm_views,
)
from pascal_calib_ros.analysis.guide.candidates import placement_of
from pascal_calib_ros.analysis.guide.guidance import Linearisation, ViewPredictor
from pascal_calib_ros.calibrate.handeye.options import HandEyeOptions
from pascal_calib_ros.calibrate.handeye.session import calibrate_hand_eye
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import resolve_target

W, H = 640, 480


@pytest.fixture(scope="module")
def arm_case():  # type: ignore[no-untyped-def]
    target = resolve_target("ring_grid_a4")
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=5, width=W, height=H, seed=3,
                                             systematic_mm=0.0))
    dets = [detect_target(img, target) for img in s.images[target.name]]
    h = calibrate_hand_eye(dets, list(s.robot_poses), target, "eye_in_hand",
                           he=HandEyeOptions(jackknife_groups=0))
    used = [k for k, v in enumerate(h.per_view) if v.used]
    poses = [s.robot_poses[k] for k in used]
    noise = ViewPredictor(Linearisation.of_refinement(h.calibration.refinement), ImageSize(W, H)).noise
    return target, arm_model(h, poses, target, noise, ImageSize(W, H)), poses


def test_candidates_include_the_latest_view_turned_about_the_optical_axis(arm_case) -> None:  # type: ignore[no-untyped-def]
    """A wrist turn of a visited view (same place, size and tilt, rolled 25-90 degrees) is a new
    motion for the hand-eye rotation: it stays among the candidates; the visited views themselves
    and turns under 20 degrees do not."""
    target, model, poses = arm_case
    trust = TrustRegion(tuple(poses))
    cands, tools = arm_candidates(model, target, trust)
    cam = model.predictor.camera_sized
    last = placement_of(target, cam, model.frames.camera_pose(poses[-1]))
    turned = [p for p, _ in cands if np.hypot(p.pixel[0] - last.pixel[0], p.pixel[1] - last.pixel[1]) < 2.0
              and abs(p.distance / last.distance - 1) < 0.01 and abs(p.tilt_deg - last.tilt_deg) < 1.0]
    rolls = sorted(abs((p.roll_deg - last.roll_deg + 180) % 360 - 180) for p in turned)
    assert rolls, "no turned copy of the latest view among the candidates"
    assert min(rolls) > 20.0 and max(rolls) > 80.0
    assert len(tools) == len(cands)


def test_the_best_tool_pose_lowers_the_predicted_hand_eye_sigma(arm_case) -> None:  # type: ignore[no-untyped-def]
    target, model, poses = arm_case
    s = suggest_arm_views(model, target, TrustRegion(tuple(poses)), n=3, goals=ArmGoals(0.05, 0.005, 0.05))
    assert len(s.suggestions) == 3
    best = s.suggestions[0]
    assert best.predicted_rotation_deg < s.rotation_deg and best.predicted_translation_mm < s.translation_mm
    assert best.view.predicted_sigma_px < s.sigma_px


def test_a_single_ring_has_a_gauge_the_prediction_leaves_out() -> None:
    """A single ring's rotation about its own axis, taken by the target's pose and every view's pose
    together, is seen by no row of the joint problem: the prediction gives it no variance (as the
    intrinsic problem, whose ring poses lack it), so the joint model's projection sigma is the
    intrinsic one or a little below (the chain adds information), not 1e4 px."""
    target = resolve_target("ring_a4")
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=12, width=W, height=H, k1=-0.1, seed=1,
                                             systematic_mm=0.0))
    dets = [detect_target(img, target) for img in s.images[target.name]]
    h = calibrate_hand_eye(dets, list(s.robot_poses), target, "eye_in_hand", he=HandEyeOptions(jackknife_groups=0))
    used = [k for k, v in enumerate(h.per_view) if v.used]
    intrinsic = ViewPredictor(Linearisation.of_refinement(h.calibration.refinement), ImageSize(W, H))
    model = arm_model(h, [s.robot_poses[k] for k in used], target, intrinsic.noise, ImageSize(W, H))
    now, joint = intrinsic.sigma_now(), model.predictor.sigma_now()
    assert 0.5 * now < joint <= 1.01 * now
    sug = suggest_arm_views(model, target, TrustRegion(tuple(s.robot_poses[k] for k in used)), n=3)
    assert sug.suggestions
    for a in sug.suggestions:
        assert 0 < a.view.predicted_sigma_px < joint
        assert 0 < a.predicted_rotation_deg < sug.rotation_deg


def test_batched_tool_poses_and_chain_rows_match_one_at_a_time(arm_case) -> None:  # type: ignore[no-untyped-def]
    """The candidates' tool poses (one batch of matrices) are :meth:`ArmFrames.tool_pose` of each,
    in both modes, and their chain rows (every perturbation in one batch) the central differences
    of each candidate's chain residuals alone."""
    from scipy.spatial.transform import Rotation

    from pascal_calib_ros.analysis.guide.arm_guidance import ArmFrames, chain_rows
    from pascal_calib_ros.calibrate.handeye.closed_form import chain_pose
    from pascal_calib_ros.geometry.transform import Transform

    target, model, poses = arm_case
    rng = np.random.default_rng(5)
    C = [Transform(Rotation.from_rotvec(rng.normal(0, 1, 3)), rng.normal(0, 0.3, 3)) for _ in range(7)]
    for mode in ("eye_in_hand", "eye_to_hand"):
        frames = ArmFrames(mode, model.frames.X, model.frames.Y)
        R, t = frames.tool_poses(np.stack([c.R for c in C]), np.array([c.translation for c in C]))
        for k, c in enumerate(C):
            g = frames.tool_pose(c)
            assert np.allclose(R[k], g.R, atol=1e-14) and np.allclose(t[k], g.translation, atol=1e-14)
    _, tools = arm_candidates(model, target, TrustRegion(tuple(poses)))
    tools = tools[:4]
    prob, x = model.problem, model.predictor.lin.x
    xy = prob.chain_params(x)
    P = np.array([np.r_[model.frames.camera_pose(g).rotvec, model.frames.camera_pose(g).translation] for g in tools])
    Jg, Jv = chain_rows(model, tools).rows(P)
    h = 1e-6
    for i, g in enumerate(tools):
        M = [chain_pose(g, model.frames.mode)]
        for k in range(prob.N_CHAIN):
            e = np.zeros(prob.N_CHAIN)
            e[k] = h
            d = (prob.chain_residuals(xy + e, P[i:i + 1], M) - prob.chain_residuals(xy - e, P[i:i + 1], M)) / (2 * h)
            assert np.allclose(Jg[i, :, prob.n_base + k], d[0], rtol=1e-7, atol=1e-6 * np.abs(d).max() + 1e-12)
        for k in range(6):
            e = np.zeros(6)
            e[k] = h
            d = (prob.chain_residuals(xy, P[i:i + 1] + e, M) - prob.chain_residuals(xy, P[i:i + 1] - e, M)) / (2 * h)
            assert np.allclose(Jv[i, :, k], d[0], rtol=1e-7, atol=1e-6 * np.abs(d).max() + 1e-12)


def test_orientation_spread_is_the_chain_rotation_rows_information() -> None:
    """:func:`orientation_spread` (trace of (N (I - R_m^T R_m))^-1) equals the least-squares
    covariance of X's rotation from the chain's rotation rows alone, x = R_i^T z - delta_i with Y's
    rotation z free, built row by row; and a candidate turned 180 degrees about a visited view's
    axis spreads the orientations more (smaller F) than that view taken again."""
    from scipy.spatial.transform import Rotation

    from pascal_calib_ros.analysis.guide.arm_guidance import orientation_spread

    rng = np.random.default_rng(2)
    visited = Rotation.from_rotvec(rng.normal(0, 0.4, (6, 3))).as_matrix()
    cands = Rotation.from_rotvec(np.r_[rng.normal(0, 0.4, (3, 3)), [[0.0, 0.0, np.pi]]]).as_matrix()
    F = orientation_spread(visited, cands)
    for k, c in enumerate(cands):
        Rs = np.concatenate([visited, c[None]])
        A = np.concatenate([np.c_[np.eye(3), -R.T] for R in Rs])  # unknowns (x, z), one block of rows per view
        assert F[k] == pytest.approx(np.trace(np.linalg.inv(A.T @ A)[:3, :3]), rel=1e-6)
    near = orientation_spread(visited, visited[:1])  # the first visited orientation again
    turned = orientation_spread(visited, (visited[0] @ Rotation.from_rotvec([0, 0, np.pi]).as_matrix())[None])
    assert turned[0] < near[0]


def test_the_spread_term_and_wide_turns_favour_spread_tool_orientations(arm_case) -> None:  # type: ignore[no-untyped-def]
    """With ``ArmRanking(spread_weight)`` the best suggestion spreads the tool orientations at least
    as much as the default ranking's (its F no larger), and with a large weight strictly more than
    the median candidate; ``wide_turns`` (the default) adds candidates, the latest view rolled by
    180 degrees among them."""
    from pascal_calib_ros.analysis.guide.arm_guidance import ArmRanking, orientation_spread

    target, model, poses = arm_case
    trust = TrustRegion(tuple(poses))
    goals = ArmGoals(0.05, 0.005, 0.05)
    visited = np.stack([g.R for g in poses])

    def spread_of(ranking: ArmRanking) -> float:
        s = suggest_arm_views(model, target, trust, n=1, goals=goals, ranking=ranking)
        return float(orientation_spread(visited, s.suggestions[0].tool.R[None])[0])

    shipped, heavy = spread_of(ArmRanking()), spread_of(ArmRanking(spread_weight=100.0))
    assert heavy <= shipped
    _, tools = arm_candidates(model, target, trust)
    assert heavy < np.median(orientation_spread(visited, np.stack([t.R for t in tools])))
    wide, _ = arm_candidates(model, target, trust, wide=10)
    narrow, _ = arm_candidates(model, target, trust)
    assert len(wide) > len(narrow)
    # the default turns the latest views wide: rolled 135-180 degrees from a visited view, among the candidates
    default = suggest_arm_views(model, target, trust, n=1, goals=goals)
    assert default.n_candidates > suggest_arm_views(model, target, trust, n=1, goals=goals,
                                                    ranking=ArmRanking(wide_turns=False)).n_candidates
    cam = model.predictor.camera_sized
    last = placement_of(target, cam, model.frames.camera_pose(poses[-1]))
    # (a turn of 180 degrees is outside the default trust region of 120 degrees around these five views)
    cands, _ = arm_candidates(model, target, TrustRegion(tuple(poses), max_turn=180.0), wide=ArmRanking().wide_views)
    rolls = [abs((p.roll_deg - last.roll_deg + 180) % 360 - 180) for p, _ in cands
             if np.hypot(p.pixel[0] - last.pixel[0], p.pixel[1] - last.pixel[1]) < 2.0
             and abs(p.distance / last.distance - 1) < 0.01 and abs(p.tilt_deg - last.tilt_deg) < 1.0]
    assert max(rolls) > 170.0
