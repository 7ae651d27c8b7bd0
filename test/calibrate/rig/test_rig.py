"""Joint rig calibration (calibrate/rig/calibration.py) on rendered stereo pairs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from rig_sessions import GRID, calibrated, det_lists, rendered, rotation_error_deg

from pascal_calib_ros.analysis.statistics.rig import rig_camera_projection
from pascal_calib_ros.calibrate.intrinsic.result import CalibrationError
from pascal_calib_ros.calibrate.rig.calibration import RigError, RigOptions, calibrate_rig
from pascal_calib_ros.calibrate.rig.start import RigConnectivityError
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.targets import resolve_target


def _rig_errors(res, session) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Per-axis rotation (deg, about the right camera's axes) and translation (mm) errors."""
    E, Et = res.extrinsics[1], session.extrinsic(1)
    return rotation_error_deg(E.R, Et.R), 1000 * (E.translation - Et.translation)


def test_pair_recovers_rig_and_intrinsics_within_sigma() -> None:
    """A rendered head (baseline 12 cm, 2 deg, 640x480, ring grid): the rig transform and both
    cameras' f and c within 4 sigma of the truth, sigma small enough to matter."""
    s, res = rendered("pair"), calibrated("pair")
    dr, dt = _rig_errors(res, s)
    sr, st = res.extrinsic_sigma[1]
    assert np.all(np.abs(dr) < 4 * sr) and np.all(np.abs(dt) < 4 * st), (dr, sr, dt, st)
    assert np.linalg.norm(dr) < 0.02 and np.linalg.norm(dt) < 0.3, (dr, dt)
    assert np.linalg.norm(sr) < 0.05 and np.linalg.norm(st) < 0.3, (sr, st)
    for c in range(2):
        K, Kt, std = res.cameras[c].K, s.spec.cameras[c].camera.K, res.cameras[c].std
        for name, (i, j) in {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}.items():
            assert abs(K[i, j] - Kt[i, j]) < 4 * std[name], (c, name, K[i, j] - Kt[i, j], std[name])
        assert rig_camera_projection(res, c) is not None  # mrcal's projection uncertainty through the rig
    # the pose of the right camera in the left's frame is the inverse, with its own sigma
    P = res.pose_in_reference(1)
    assert np.allclose(P.translation, s.spec.cameras[1].pose.translation, atol=3e-4)
    assert np.all(res.pose_sigma[1][1] > 0)
    # the shot the right camera saw whole and the left in part (a grid labelled up to a shift) is used by both
    single = s.names.index("single_001")
    assert not s.seen[0, single] and s.seen[1, single]
    assert res.used[0, single] and res.used[1, single]
    assert res.rms < 0.2


def _turned(dets: list[Detection]) -> list[Detection]:
    """The detections with every circle relabelled by the grid's 180 degree turn."""
    grid = resolve_target(GRID)
    ctr = np.array([c.center for c in grid.circles])
    rad = np.array([c.radius for c in grid.circles])
    mid = (ctr.min(0) + ctr.max(0)) / 2
    perm = [int(np.argmin(np.linalg.norm(ctr - p, axis=1) + abs(rad - r))) for p, r in zip(2 * mid - ctr, rad,
                                                                                           strict=True)]
    return [replace(d, edges=[replace(e, circle=perm[e.circle]) for e in d.edges]) for d in dets]


def test_flipped_shot_is_relabelled_and_a_one_camera_shot_serves_that_camera() -> None:
    """One shot's right view labelled turned by 180 degrees (ring_grid_a4 looks the same): the
    joint calibration labels it consistently and lands where the untouched session does; a
    pipeline that keeps the detected labels (relabel=False) lands >= 20x further off. A shot whose
    left view is missing still serves the right camera's intrinsics."""
    s = rendered("pair")
    dets = det_lists("pair")
    dets[1][3] = _turned([dets[1][3]])[0]
    dets[0][5] = Detection(dets[0][5].width, dets[0][5].height, name=dets[0][5].name, reason="no image of this shot")
    grid = resolve_target(GRID)
    res = calibrate_rig(dets, grid, ["left", "right"])
    assert res.relabelled >= 2  # the turned view and the partial grid of single_001
    assert res.used[1, 5] and not res.used[0, 5] and res.used[1, 3] and res.used[0, 3]
    dr, dt = _rig_errors(res, s)
    ref_r, ref_t = _rig_errors(calibrated("pair"), s)
    assert np.linalg.norm(dr) < 0.02 and np.linalg.norm(dt) < 0.3, (dr, dt)
    naive = calibrate_rig(dets, grid, ["left", "right"], RigOptions(relabel=False))
    nr, nt = _rig_errors(naive, s)
    assert np.linalg.norm(nr) > 20 * max(np.linalg.norm(dr), np.linalg.norm(ref_r)), (nr, dr)
    assert np.linalg.norm(nt) > 20 * max(np.linalg.norm(dt), np.linalg.norm(ref_t)), (nt, dt)


def test_disconnected_rig_is_refused_naming_the_groups() -> None:
    """A third camera whose shots no other camera saw: refused before any calibration, naming
    the groups."""
    dets = det_lists("pair")
    n = len(dets[0])
    none = [Detection(640, 480, name=f"x{k}", reason="no image of this shot") for k in range(n)]
    cams = [dets[0] + none, dets[1] + none, none + dets[0]]
    with pytest.raises(RigConnectivityError, match=r"\{left, right\}; \{top\}"):
        calibrate_rig(cams, resolve_target(GRID), ["left", "right", "top"])


def test_bad_rigs_are_refused_with_the_reason() -> None:
    dets = det_lists("pair")
    with pytest.raises(RigError, match="single ring"):
        calibrate_rig(dets, resolve_target("ring_a4"), ["left", "right"])
    with pytest.raises(RigError, match="at least two cameras"):
        calibrate_rig(dets[:1], resolve_target(GRID), ["left"])
    with pytest.raises(RigError, match="one detection per shot"):
        calibrate_rig([dets[0], dets[1][:-1]], resolve_target(GRID), ["left", "right"])
    with pytest.raises(RigError, match="distinct name"):
        calibrate_rig(dets, resolve_target(GRID), ["a", "a"])
    few = [dets[0], [d if k < 2 else replace(d, reason="blurred") for k, d in enumerate(dets[1])]]
    with pytest.raises(CalibrationError, match="camera right"):
        calibrate_rig(few, resolve_target(GRID), ["left", "right"])


def test_fisheye_pair_calibrates() -> None:
    """An equidistant pair of about 190 degrees: calibrated jointly with its own lens model."""
    s, res = rendered("fisheye"), calibrated("fisheye")
    dr, dt = _rig_errors(res, s)
    sr, st = res.extrinsic_sigma[1]
    assert np.linalg.norm(dr) < 0.02 and np.linalg.norm(dt) < 0.2, (dr, dt)
    assert np.all(np.abs(dr) < 4 * sr) and np.all(np.abs(dt) < 4 * st), (dr, sr, dt, st)
    for c in range(2):
        assert res.cameras[c].model == "equidistant"
        assert abs(res.cameras[c].K[0, 0] / s.spec.cameras[c].camera.K[0, 0] - 1) < 1e-3


def test_charuco_pair_matches_corners_by_id_in_shots_each_camera_sees_in_part() -> None:
    """A ChArUco seen whole by one camera and in part by the other (or in different parts by
    both) serves both cameras: its corners are matched by id; the rig within 4 sigma."""
    from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
    from pascal_calib_ros.detect.target_detector import detect_target
    from pascal_calib_ros.sim.rig import RigSpec, render_rig, stereo_pair

    target = resolve_target("charuco_a3")
    s = render_rig(target, RigSpec(stereo_pair(640, 480), shots=6, single_shots=4, seed=2, size_range=(0.65, 0.95)))
    dets = [[detect_target(im, target, name=n) for im, n in zip(ims, s.names, strict=True)] for ims in s.images]
    res = calibrate_rig(dets, target, ["left", "right"], RigOptions(CalibrationOptions()))
    partial = [k for k in range(len(s.names)) if s.seen[:, k].sum() == 1 and res.used[:, k].all()]
    assert partial, res.reasons
    dr, dt = _rig_errors(res, s)
    sr, st = res.extrinsic_sigma[1]
    assert np.all(np.abs(dr) < 4 * sr) and np.all(np.abs(dt) < 4 * st), (dr, sr, dt, st)
    assert np.linalg.norm(dr) < 0.1 and np.linalg.norm(dt) < 1.0, (dr, dt)
