"""The node's stereo calibration, ROS-free (workflows/stereo_session.py): the checks a published
result must pass, the files and records, the answer."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from rig_sessions import GRID, calibrated, det_lists

from pascal_calib_ros.io.calibration_json import read_calibration_json
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.targets import resolve_target
from pascal_calib_ros.workflows.stereo import StereoOptions, StereoOutcome, stereo_outcome
from pascal_calib_ros.workflows.stereo_session import (
    answer_line,
    stereo_doubts,
    stereo_output_dir,
)


@pytest.fixture(scope="module")
def outcome() -> StereoOutcome:
    return stereo_outcome(calibrated("pair"), det_lists("pair"), resolve_target(GRID),
                          StereoOptions(camera_name="head"))


def test_a_good_pair_has_no_doubts_and_bad_ones_say_why(outcome: StereoOutcome) -> None:
    assert stereo_doubts(outcome) == []
    moved = dataclasses.replace(outcome, epipolar_rms=2.5)
    (why,) = stereo_doubts(moved)
    assert why.startswith("epipolar RMS 2.500 px (limit 1.0 px)") and "synchronise the cameras" in why
    loose = dataclasses.replace(outcome, stereo=dataclasses.replace(outcome.stereo,
                                                                    sigma_rotation_deg=np.array([0.4, 0.4, 0.1])))
    (why,) = stereo_doubts(loose)
    assert why.startswith(f"the rig transform is not determined well enough: sigma {np.sqrt(0.33):.3f} deg"), why
    unknown = dataclasses.replace(outcome, stereo=dataclasses.replace(outcome.stereo,
                                                                      sigma_translation_mm=np.full(3, np.nan)))
    assert stereo_doubts(unknown) == ["the rig transform has no uncertainty (no covariance)"]


def test_files_records_and_answer(outcome: StereoOutcome, tmp_path: Path) -> None:
    files = outcome.write(tmp_path)
    assert [f.name for f in files] == ["left.yaml", "right.yaml", "stereo.yaml",
                                                      "left.calibration.json", "right.calibration.json"]
    for c, side in enumerate(("left", "right")):
        record = read_calibration_json(tmp_path / f"{side}.calibration.json")
        assert record.camera_name == f"head/{side}" and record.covariance is not None
        # the record's sigmas are the joint estimate's (the rig's covariance, not the camera's own start)
        sigmas = dict(zip(record.parameters, np.sqrt(np.diag(record.covariance)), strict=True))
        assert sigmas["fx"] == pytest.approx(outcome.rig.cameras[c].std["fx"], rel=1e-9)
        np.testing.assert_allclose(record.camera.K, read_camera_yaml(tmp_path / f"{side}.yaml").K)
        np.testing.assert_allclose(record.camera.K, outcome.rig.cameras[c].K)
    line = answer_line(outcome, files)
    assert line.startswith("left: fx=") and "; right: fx=" in line and "X_right = R X_left + T: T=[-0.1" in line
    assert f"yaml={tmp_path / 'left.yaml'}, right.yaml, stereo.yaml" in line
    assert stereo_output_dir("head", "") == Path.home() / ".ros" / "pascal_calib" / "head"
    assert stereo_output_dir("head", str(tmp_path)) == tmp_path
