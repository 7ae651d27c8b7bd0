from pathlib import Path

import numpy as np
import pytest
import yaml

from pascal_calib_ros.io.camera_yaml import CameraInfoData, CameraYamlError, read_camera_yaml, write_camera_yaml


def test_round_trip_in_camera_calibration_parsers_layout(tmp_path: Path) -> None:
    K = np.array([[801.5, 0.0, 410.25], [0.0, 803.0, 295.5], [0.0, 0.0, 1.0]])
    D = np.array([-0.3, 0.08, 0.001, -0.0005, 0.01])
    p = write_camera_yaml(tmp_path / "c.yaml", CameraInfoData(800, 600, "cam", K, D))
    doc = yaml.safe_load(p.read_text())
    assert list(doc) == ["image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
                         "distortion_coefficients", "rectification_matrix", "projection_matrix"]
    assert doc["camera_matrix"]["rows"] == 3 and doc["projection_matrix"]["cols"] == 4
    back = read_camera_yaml(p)
    assert np.array_equal(back.K, K) and np.array_equal(back.D, D) and back.camera_name == "cam"
    assert np.array_equal(back.projection[:, :3], K) and np.all(back.projection[:, 3] == 0)
    assert np.array_equal(back.R, np.eye(3))


def test_bad_files(tmp_path: Path) -> None:
    p = tmp_path / "x.yaml"
    p.write_text("image_width: 3\n")
    with pytest.raises(CameraYamlError):
        read_camera_yaml(p)
    with pytest.raises(CameraYamlError):
        read_camera_yaml(tmp_path / "missing.yaml")
