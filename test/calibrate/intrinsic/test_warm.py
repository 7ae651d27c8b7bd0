"""The warm start of the calibration (calibrate/intrinsic/warm.py): a session that grows view by view gets the
cold calibration's answer, in fewer steps; anything but a grown session, and a calibration that did
not go the plain way, is calibrated cold.

The tolerance is the cold calibration's own: its Levenberg-Marquardt stops where the cost's decrease
falls below 1e-10 of it, and the edge rows' Jacobian is exact only at the foot point (one Gauss-Newton
step on a circle's angle), so the point it stops at depends, within that, on where it came from: about
1e-5 px of K for a ring, 5e-4 px for the ring grid, whose small tilted circles leave the foot point
furthest out (a warm start lands as far off; with an exact Jacobian, by central differences, the
two agree 10 to 20 times better)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.calibrate.intrinsic.warm import calibrate_warm
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import Target, resolve_target

K_TOL = {"ring_a4": 3e-5, "ring_grid_a4": 1e-3}  # px (module docstring)


@pytest.fixture(scope="module", params=["ring_a4", "ring_grid_a4"])
def session(request: pytest.FixtureRequest) -> tuple[Target, list[Detection]]:
    """9 views of a camera on an arm (640x480, mild distortion, the sensor's noise and blur)."""
    target = resolve_target(request.param)
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=9, width=640, height=480, k1=-0.1, seed=5))
    return target, [detect_target(im, target, name=n) for im, n in zip(s.images[target.name], s.names, strict=True)]


def test_a_session_grown_view_by_view_gets_the_cold_calibration(session: tuple[Target, list[Detection]]) -> None:
    target, dets = session
    opt = CalibrationOptions()
    _, start = calibrate_warm(dets[:6], target, opt)
    assert start is not None, "a plain calibration gives the next call's start"
    for n in (7, 8, 9):
        warm, nxt = calibrate_warm(dets[:n], target, opt, start)
        cold = calibrate(dets[:n], target, opt)
        assert warm.refinement is not None and cold.refinement is not None
        assert warm.refinement.nfev < cold.refinement.nfev  # it did start warm
        np.testing.assert_allclose(warm.K, cold.K, rtol=0, atol=K_TOL[target.name])
        np.testing.assert_allclose(warm.D, cold.D, rtol=0, atol=K_TOL[target.name] / 100)
        assert [v.used for v in warm.views] == [v.used for v in cold.views]
        assert [v.rejected_edges for v in warm.views] == [v.rejected_edges for v in cold.views]
        assert warm.rms == pytest.approx(cold.rms, rel=1e-6)
        assert warm.std["fx"] == pytest.approx(cold.std["fx"], rel=1e-4)
        assert nxt is not None and len(nxt.dets) == n
        start = nxt


def test_anything_but_a_grown_session_is_calibrated_cold(session: tuple[Target, list[Detection]]) -> None:
    target, dets = session
    opt = CalibrationOptions()
    _, start = calibrate_warm(dets[:7], target, opt)
    assert start is not None and start.applies(dets[:8], target, opt) and start.applies(dets[:7], target, opt)
    other = [replace(d) for d in dets]  # the same views, other detections
    for views, tgt, o in ((dets[:6], target, opt), (dets[1:8], target, opt), (other[:8], target, opt),
                          (dets[:8], resolve_target(target.name), opt),
                          (dets[:8], target, replace(opt, distortion="radial"))):
        assert not start.applies(views, tgt, o)
        warm, _ = calibrate_warm(views, tgt, o, start)
        cold = calibrate(views, tgt, o)
        np.testing.assert_array_equal(warm.K, cold.K)  # the cold path itself


def _shaken(det: Detection, px: float, seed: int) -> Detection:
    """The view with every edge point moved by ``px`` (normal noise): an outlier view."""
    rng = np.random.default_rng(seed)
    return replace(det, edges=[replace(e, points=e.points + rng.normal(0, px, e.points.shape)) for e in det.edges])


def test_a_calibration_that_is_not_plain_gives_no_start(session: tuple[Target, list[Detection]]) -> None:
    target, dets = session
    opt = CalibrationOptions()
    cal, start = calibrate_warm(dets[:7], target, replace(opt, refine=False))
    assert not cal.refined and start is None
    # a view dropped as an outlier after the first refinement: the next call is cold
    shaken = [*dets[:3], _shaken(dets[3], 1.0, 0), *dets[4:7]]
    cal, start = calibrate_warm(shaken, target, opt)
    assert not cal.views[3].used and "outlier" in cal.views[3].reason and start is None
    # so is a grown session whose new view would be dropped
    _, start = calibrate_warm(dets[:6], target, opt)
    assert start is not None
    grown = [*dets[:6], _shaken(dets[6], 1.0, 1)]
    warm, nxt = calibrate_warm(grown, target, opt, start)
    cold = calibrate(grown, target, opt)
    assert not warm.views[6].used and nxt is None
    np.testing.assert_array_equal(warm.K, cold.K)  # computed cold
