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


@pytest.mark.parametrize(("field", "value", "said"), [
    ("image_width", None, "image_width must be a positive whole number of pixels, got None"),
    ("image_height", "480", "image_height must be a positive whole number"),
    ("image_width", -640, "image_width must be a positive whole number"),
    ("image_width", ..., "missing image_width"),
    ("distortion_model", None, "distortion_model must be a string, got None"),
    ("camera_matrix", None, "missing camera_matrix"),
    ("camera_matrix", {"rows": 3, "cols": 3, "data": [None] * 9}, "camera_matrix: data must be a list of finite"),
    ("distortion_coefficients", {"rows": 1, "cols": None, "data": [0.0] * 5}, "distortion_coefficients: data and"),
    ("projection_matrix", 7, "projection_matrix: not a matrix"),
])
def test_null_or_malformed_fields_are_named(tmp_path: Path, field: str, value: object, said: str) -> None:
    """A null, missing or mistyped field is a CameraYamlError naming it (never a TypeError), and
    reading the file by its content says the same (CalibrationFileError, a PascalCalibError)."""
    from pascal_calib_ros.errors import PascalCalibError
    from pascal_calib_ros.io.calibration_files import read_calibration_file

    p = write_camera_yaml(tmp_path / "c.yaml", CameraInfoData(640, 480, "cam", np.diag([500.0, 500.0, 1.0]),
                                                              np.zeros(5)))
    doc = yaml.safe_load(p.read_text())
    if value is ...:
        del doc[field]
    else:
        doc[field] = value
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(CameraYamlError, match=f"c.yaml: {said}"):
        read_camera_yaml(p)
    with pytest.raises(PascalCalibError, match=said):
        read_calibration_file(p)
