"""The warm start of the hand-eye estimate (calibrate/handeye/warm.py): a session that grows view by
view gets the cold estimate; the chain refinement's start follows a session relabelled as a whole
and is refused for anything but a grown session.

Tolerances as in test_warm.py: the cold refinements stop, within the edge Jacobian's resolution,
where their path led them; X agrees to about 1e-6 mm for a ring, 5e-4 mm and 5e-5 deg for the ring
grid (a few thousandths of their sigmas)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pascal_calib_ros.calibrate.handeye import HandEyeOptions
from pascal_calib_ros.calibrate.handeye.session import calibrate_hand_eye, calibrate_hand_eye_warm
from pascal_calib_ros.calibrate.handeye.warm import HandEyeStart
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.sim.arm import ArmSession, ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import Target, resolve_target

TOL = {"ring_a4": (3e-5, 3e-6, 1e-5), "ring_grid_a4": (1e-3, 1e-3, 1e-4)}  # K px, X mm, X deg


@pytest.fixture(scope="module", params=[("ring_a4", "eye_in_hand"), ("ring_grid_a4", "eye_in_hand"),
                                        ("ring_grid_a4", "eye_to_hand")])
def session(request: pytest.FixtureRequest) -> tuple[Target, ArmSession, list[Detection]]:
    """9 views of an arm session (640x480, mild distortion, the arm's noise and systematic error)."""
    name, mode = request.param
    target = resolve_target(name)
    s = simulate_arm_session(target, ArmSpec(mode=mode, views=9, width=640, height=480, k1=-0.1, seed=3))
    return target, s, [detect_target(im, target, name=n) for im, n in zip(s.images[target.name], s.names,
                                                                          strict=True)]


def test_a_session_grown_view_by_view_gets_the_cold_estimate(session) -> None:
    target, s, dets = session
    mode, opt = s.spec.mode, CalibrationOptions()
    he = HandEyeOptions(mode=mode, jackknife_groups=0)
    robot = list(s.robot_poses)
    _, start = calibrate_hand_eye_warm(dets[:6], robot[:6], target, mode, opt, he)
    assert start.intrinsic is not None and len(start.first_pass)
    k_tol, mm_tol, deg_tol = TOL[target.name]
    for n in (7, 8, 9):
        warm, nxt = calibrate_hand_eye_warm(dets[:n], robot[:n], target, mode, opt, he, start)
        cold = calibrate_hand_eye(dets[:n], robot[:n], target, mode, opt, he)
        np.testing.assert_allclose(warm.calibration.K, cold.calibration.K, rtol=0, atol=k_tol)
        np.testing.assert_allclose(warm.hand_eye.translation, cold.hand_eye.translation, rtol=0, atol=mm_tol / 1000)
        assert np.degrees((warm.hand_eye.rotation * cold.hand_eye.rotation.inv()).magnitude()) < deg_tol
        np.testing.assert_allclose(warm.translation_std_mm, cold.translation_std_mm, rtol=1e-3)
        np.testing.assert_allclose(warm.rotation_std_deg, cold.rotation_std_deg, rtol=1e-3)
        assert warm.robot_error_mm == pytest.approx(cold.robot_error_mm, rel=1e-3)
        assert [v.used for v in warm.per_view] == [v.used for v in cold.per_view]
        kept = [k for k, v in enumerate(warm.per_view) if v.used]
        assert nxt.kept == tuple(kept)
        assert start.chain_start(kept, list(nxt.poses), [0.0] * len(kept), 7) is not None  # the chain started warm
        start = nxt


def test_the_start_applies_to_a_grown_session_only(session) -> None:
    target, s, dets = session
    mode, opt = s.spec.mode, CalibrationOptions()
    he = HandEyeOptions(mode=mode, jackknife_groups=0)
    robot = list(s.robot_poses)
    _, start = calibrate_hand_eye_warm(dets[:7], robot[:7], target, mode, opt, he)
    assert start.applies(dets[:8], robot[:8], he) and start.applies(dets[:7], robot[:7], he)
    moved = [*robot[:2], robot[2] @ Transform.from_rotvec([0, 0, 0], [0, 0, 1e-4]), *robot[3:]]
    for views, poses, h in ((dets[:6], robot[:6], he), (dets[:8], moved[:8], he),
                            (dets[:8], robot[:8], replace(he, robot_sigma_mm=0.2)),
                            ([replace(d) for d in dets[:8]], robot[:8], he)):
        assert not start.applies(views, poses, h)
    # not applicable: the cold estimate itself
    warm, _ = calibrate_hand_eye_warm(dets[:8], moved[:8], target, mode, opt, he, start)
    cold = calibrate_hand_eye(dets[:8], moved[:8], target, mode, opt, he)
    np.testing.assert_array_equal(warm.hand_eye.matrix, cold.hand_eye.matrix)


def _start(poses: list[Transform], X: Transform, Y: Transform) -> HandEyeStart:
    x = np.r_[X.rotvec, X.translation, Y.rotvec, Y.translation,
              np.concatenate([np.r_[p.rotvec, p.translation, 0.1 * k] for k, p in enumerate(poses)])]
    return HandEyeStart((), (), HandEyeOptions(), None, tuple(range(len(poses))), tuple(poses), x)


def test_chain_start_follows_a_session_relabelled_as_a_whole() -> None:
    rng = np.random.default_rng(0)
    poses = [Transform.from_rotvec(rng.normal(size=3), rng.normal(size=3)) for _ in range(4)]
    X, Y = Transform.from_rotvec(rng.normal(size=3), rng.normal(size=3)), Transform.from_rotvec([0.1, 0, 0], [1, 0, 0])
    start = _start(poses, X, Y)
    new = Transform.from_rotvec([0.2, 0.1, 0.3], [0.1, 0.2, 0.5])
    same = start.chain_start([0, 1, 2, 3, 4], [*poses, new], [0.0] * 4 + [-0.3], 7)
    assert same is not None
    np.testing.assert_array_equal(same[:12 + 28], start.first_pass)
    np.testing.assert_allclose(same[-7:], np.r_[new.rotvec, new.translation, -0.3])
    T = Transform.from_rotvec([0, 0, np.pi], [0.05, 0.02, 0.0])  # a 180 degree symmetry of the sheet
    x = start.chain_start([0, 1, 2, 3, 4], [*(p @ T for p in poses), new], [0.0] * 5, 7)
    assert x is not None
    np.testing.assert_allclose(x[:6], start.first_pass[:6])  # X stays
    np.testing.assert_allclose(Transform.from_rotvec(x[6:9], x[9:12]).matrix, (Y @ T).matrix, atol=1e-12)
    for i, p in enumerate(poses):
        b = 12 + 7 * i
        np.testing.assert_allclose(Transform.from_rotvec(x[b:b + 3], x[b + 3:b + 6]).matrix, (p @ T).matrix,
                                   atol=1e-12)
        assert x[b + 6] == pytest.approx(0.1 * i)  # the edge offsets stay
    # one view alone turned, or the previous views not the first: no warm chain
    assert start.chain_start([0, 1, 2, 3], [poses[0] @ T, *poses[1:]], [0.0] * 4, 7) is None
    assert start.chain_start([0, 2, 3, 4], [poses[0], *poses[2:], new], [0.0] * 4, 7) is None
