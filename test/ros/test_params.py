"""The node parameter table per mode and the checks of the stereo mode's parameters (ros/params.py)."""

from __future__ import annotations

from pascal_calib_ros.ros.params import PARAMS, params_for, validate_parameters


def _defaults(mode: str) -> dict:
    return {p.name: p.default for p in params_for(mode)}


def test_each_mode_declares_its_parameters() -> None:
    mono, stereo = {p.name for p in params_for("mono")}, {p.name for p in params_for("stereo")}
    assert {"mode", "target", "min_views", "sync_slop"} <= stereo and "sync_slop" not in mono
    assert {"hand_eye", "set_camera_info_service", "calibration_file"} <= mono - stereo
    assert {"left_set_camera_info_service", "right_set_camera_info_service"} <= stereo - mono
    assert mono | stereo == {p.name for p in PARAMS}
    assert params_for("triple") == params_for("mono")  # the mono node then refuses the mode
    assert validate_parameters(_defaults("mono"), {}) == [] and validate_parameters(_defaults("stereo"), {}) == []


def test_stereo_parameters_that_cannot_work_are_refused_with_the_reason() -> None:
    current = _defaults("stereo")
    assert validate_parameters({"mode": "triple"}, current) == ["mode='triple' is not one of 'mono', 'stereo'"]
    (why,) = validate_parameters({"sync_slop": -0.5}, current)
    assert why.startswith("sync_slop=-0.5: the largest stamp difference of a pair in seconds, 0 or more")
    (why,) = validate_parameters({"right_set_camera_info_service": "left/set_camera_info"}, current)
    assert "both 'left/set_camera_info'" in why and "one service would write both calibrations" in why
    (why,) = validate_parameters({"right_frame": "left_camera_optical_frame"}, current)
    assert "left_frame and right_frame are both" in why
    assert validate_parameters({"sync_slop": 0.0}, current) == []
