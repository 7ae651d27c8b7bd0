"""What a calibration leaves behind, the same from the CLI and the node."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.io.calibration_json import read_calibration_json
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.targets import Target
from pascal_calib_ros.workflows.calibration_record import record_of_result
from pascal_calib_ros.workflows.intrinsic import run_intrinsic
from pascal_calib_ros.workflows.outputs import (
    ReportRequest,
    ResultPaths,
    calibration_file_path,
    camera_info_data,
    output_folder,
    write_calibration,
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
    yaml_path, json_path = write_calibration(record_of_result(res, "wrist"), tmp_path / "c.yaml")
    back = read_camera_yaml(yaml_path)
    assert back.camera_name == "wrist" and np.allclose(back.K, res.K) and np.allclose(back.D, res.D)
    assert json_path == tmp_path / "c.calibration.json"
    rec = read_calibration_json(json_path)  # one record, two files: the same camera in both
    assert np.array_equal(rec.camera.K, back.K) and np.array_equal(rec.camera.D, back.D)


def test_an_outcome_writes_one_set_of_files_wherever_its_paths_say(ring_target: Target, ring_session,
                                                                    tmp_path: Path) -> None:
    """The node's result set (one folder) and the CLI (its options' paths) write through the same
    ``outcome.write``: the camera YAML, its versioned record (the one calibration.json), the report;
    the CameraInfo the node publishes is the outcome's ``camera_info``."""
    _, _, dets = ring_session
    out = run_intrinsic(dets, ring_target, CalibrationOptions())
    node = out.write(ResultPaths.in_folder(tmp_path / "set", "wrist", report=True), "wrist",
                     ReportRequest(dets, None))
    assert [p.name for p in node.paths] == ["wrist.yaml", "wrist.calibration.json", "report.pdf", "report.png",
                                            "report.json"] and not node.warnings
    cli = out.write(ResultPaths(tmp_path / "cli" / "c.yaml"), "wrist")
    assert [p.name for p in cli.paths] == ["c.yaml", "c.calibration.json"]
    assert (tmp_path / "cli" / "c.yaml").read_text() == (tmp_path / "set" / "wrist.yaml").read_text()
    record = read_calibration_json(tmp_path / "set" / "wrist.calibration.json")
    assert record.covariance is not None and np.allclose(record.camera.K, out.assessment.result.K)
    doc = json.loads((tmp_path / "set" / "report.json").read_text())
    assert len(doc["views"]) == len(dets)
    info = out.camera_info("wrist")
    assert info.camera_name == "wrist" and np.array_equal(info.K, out.assessment.result.K)
    # a report that cannot be written is a warning, never a lost calibration
    (tmp_path / "blocked").write_text("a file where the report's folder should be")
    bad = out.write(ResultPaths(tmp_path / "ok.yaml", report_dir=tmp_path / "blocked"), "wrist",
                    ReportRequest(dets, None))
    assert bad.warnings and bad.warnings[0].startswith("report not written") and (tmp_path / "ok.yaml").exists()


def test_the_answer_says_the_result_and_why_there_is_no_cross_validation(ring_target: Target, ring_session) -> None:
    _, _, dets = ring_session
    out = run_intrinsic(dets, ring_target, CalibrationOptions(min_views=6), with_cross_validation=True)  # needs 12
    answer = out.answer("/tmp/c.yaml")
    assert answer.startswith("fx=") and "yaml=/tmp/c.yaml" in answer and "projection sigma" in answer
    assert "WARNING: cross-validation not possible" in answer and out.halves_agree is None
    with pytest.raises(ValueError, match="distance"):
        run_intrinsic(dets, ring_target, CalibrationOptions(), distance=0.0)
