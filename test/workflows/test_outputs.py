"""What a calibration leaves behind, the same from the CLI and the node."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pascal_calib_ros.calibrate.options import CalibrationOptions
from pascal_calib_ros.calibrate.pipeline import calibrate
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.targets import Target
from pascal_calib_ros.workflows.intrinsic import run_intrinsic
from pascal_calib_ros.workflows.outputs import (
    calibration_file_path,
    calibration_json,
    camera_info_data,
    output_folder,
    write_camera_file,
)


def test_results_never_go_to_the_drivers_camera_info_folder() -> None:
    """Without output_dir a node writes under ~/.ros/pascal_calib/<camera>; ~/.ros/camera_info (the
    file the driver loads at its next start) changes only through ~/commit."""
    assert calibration_file_path("cam", "", "/x/c.yaml") == Path("/x/c.yaml")
    assert calibration_file_path("cam", "/out") == Path("/out/cam.yaml")
    home = Path.home() / ".ros" / "pascal_calib" / "cam"
    assert output_folder("cam") == home and calibration_file_path("cam") == home / "cam.yaml"
    assert output_folder("cam", "~/x") == Path.home() / "x"


def test_the_camera_yaml_and_json_of_a_calibration(ring_target: Target, ring_session, tmp_path: Path) -> None:
    _, _, dets = ring_session
    res = calibrate(dets, ring_target)
    info = camera_info_data(res, "wrist")
    assert np.allclose(info.projection[:, :3], res.K) and np.all(info.projection[:, 3] == 0)
    back = read_camera_yaml(write_camera_file(res, tmp_path / "c.yaml", "wrist"))
    assert back.camera_name == "wrist" and np.allclose(back.K, res.K) and np.allclose(back.D, res.D)
    doc = json.loads(json.dumps(calibration_json(res), default=float))
    assert doc["summary"].startswith("fx=") and len(doc["views"]) == len(dets)


def test_the_answer_says_the_result_and_why_there_is_no_cross_validation(ring_target: Target, ring_session) -> None:
    _, _, dets = ring_session
    out = run_intrinsic(dets, ring_target, CalibrationOptions(min_views=6), with_cross_validation=True)  # needs 12
    answer = out.answer("/tmp/c.yaml")
    assert answer.startswith("fx=") and "yaml=/tmp/c.yaml" in answer and "projection sigma" in answer
    assert "WARNING: cross-validation not possible" in answer and out.halves_agree is None
    with pytest.raises(ValueError, match="distance"):
        run_intrinsic(dets, ring_target, CalibrationOptions(), distance=0.0)
