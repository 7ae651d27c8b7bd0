"""The model-bias verdict on a lens the model cannot describe (sim/model_bias_study.py; the
README's table runs all 26 sessions with `pascal-calib study model-bias`)."""

from pascal_calib_ros.analysis.statistics.assessment import assess
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.sim.render import render_view
from pascal_calib_ros.sim.session import session_views
from pascal_calib_ros.studies.model_bias_study import cases
from pascal_calib_ros.targets import resolve_target


def test_a_wide_angle_lens_calibrated_with_plumb_bob_is_called_biased_and_rational_is_not() -> None:
    case = [c for c in cases() if c.label.startswith("rational")][1]  # 115 deg, seed 22, 12 views
    assert case.biased
    target = resolve_target(case.target)
    cam = case.spec.camera()
    dets = [detect_target(render_view(target, cam, pose, sens).image, target, name=n)
            for n, pose, sens in session_views(target, case.spec)]
    wrong = assess(calibrate(dets, target, CalibrationOptions(distortion="plumb_bob")))
    verdict = wrong.bias
    assert verdict is not None and verdict.detected and verdict.radial_significant + verdict.regional_significant >= 2
    assert verdict.hint in wrong.warnings and "rational_polynomial" in verdict.hint
    right = assess(calibrate(dets, target, CalibrationOptions(distortion="rational_polynomial")))
    assert right.bias is not None and not right.bias.detected
    assert not any("not noise" in w for w in right.warnings)
