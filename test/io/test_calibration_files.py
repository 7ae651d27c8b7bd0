"""Reading any calibration file by its content (``io/calibration_files.py``), ``calibration.json``
(``io/calibration_json.py``) and the hand-eye exports (``io/hand_eye_export.py``)."""

from __future__ import annotations

import shlex
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from export_cases import FISHEYE, PLUMB, RATIONAL

from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.calibration_files import read_calibration_file
from pascal_calib_ros.io.calibration_json import (
    CalibrationRecord,
    read_calibration_json,
    sidecar_path,
    write_calibration_json,
)
from pascal_calib_ros.io.camera_yaml import CameraInfoData, write_camera_yaml
from pascal_calib_ros.io.format_error import CalibrationFileError
from pascal_calib_ros.io.hand_eye_export import static_transform_text, transform_of_urdf_origin, urdf_joint_text
from pascal_calib_ros.io.kalibr_camchain import KalibrCamera, write_kalibr_camchain
from pascal_calib_ros.io.mrcal_model import mrcal_model_of_camera, write_mrcal_model
from pascal_calib_ros.io.opencv_storage import write_opencv_storage

COV = np.diag([0.3, 0.3, 0.5, 0.5, 1e-4, 1e-3, 1e-6, 1e-6, 1e-2]) ** 2
NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


def write_ros(path: Path, cam=PLUMB) -> Path:
    return write_camera_yaml(path, CameraInfoData(cam.width, cam.height, "cam", cam.K, cam.D, cam.model))


def test_every_format_is_recognised_by_its_content(tmp_path: Path) -> None:
    files = {
        "ros": write_ros(tmp_path / "a.data"),
        "opencv": write_opencv_storage(tmp_path / "b.data", RATIONAL),
        "mrcal": write_mrcal_model(tmp_path / "c.data", mrcal_model_of_camera(PLUMB)),
        "kalibr": write_kalibr_camchain(tmp_path / "d.data", [KalibrCamera(FISHEYE)]),
        "json": write_calibration_json(tmp_path / "e.data", CalibrationRecord(PLUMB, "x", "plumb_bob", NAMES, COV)),
    }
    for fmt, path in files.items():
        cf = read_calibration_file(path)
        assert cf.format == fmt, (fmt, cf.format)
        assert cf.camera.model in ("plumb_bob", "rational_polynomial", "equidistant")
    assert read_calibration_file(files["json"]).record.covariance is not None
    (tmp_path / "junk.yaml").write_text("just: words\n")
    with pytest.raises(CalibrationFileError, match="not a calibration file"):
        read_calibration_file(tmp_path / "junk.yaml")
    with pytest.raises(CalibrationFileError, match="cannot read"):
        read_calibration_file(tmp_path / "missing.yaml")
    (tmp_path / "he.yaml").write_text(yaml.safe_dump({"mode": "eye_in_hand", "translation": [0, 0, 0],
                                                      "rotation": [0, 0, 0, 1]}))
    with pytest.raises(CalibrationFileError, match="--to urdf"):
        read_calibration_file(tmp_path / "he.yaml")


def test_a_ros_yaml_gets_its_sidecar_only_when_it_holds_the_same_camera(tmp_path: Path) -> None:
    cam_yaml = write_ros(tmp_path / "cam.yaml")
    assert sidecar_path(cam_yaml).name == "cam.calibration.json"
    assert read_calibration_file(cam_yaml).record.covariance is None
    write_calibration_json(sidecar_path(cam_yaml), CalibrationRecord(PLUMB, "cam", "plumb_bob", NAMES, COV))
    cf = read_calibration_file(cam_yaml)
    assert cf.record.parameters == NAMES and np.allclose(cf.record.covariance, COV)
    write_ros(cam_yaml, RATIONAL)  # recalibrated: the old sidecar no longer applies
    cf = read_calibration_file(cam_yaml)
    assert cf.record.covariance is None and "another camera" in cf.notes[0]


def test_calibration_json_round_trip_and_checks(tmp_path: Path) -> None:
    hull = np.array([[10.0, 10.0], [300.0, 12.0], [200.0, 250.0]])
    rec = CalibrationRecord(RATIONAL, "front", "rational_polynomial", NAMES, COV, [hull], 0.05, 14,
                            {"median_px": 0.01, "worst_px": 0.03, "distance_m": 0.5}, note="n")
    back = read_calibration_json(write_calibration_json(tmp_path / "c.json", rec))
    assert np.array_equal(back.camera.K, RATIONAL.K) and np.array_equal(back.camera.D, RATIONAL.D)
    assert back.std["cx"] == pytest.approx(0.5) and back.views_used == 14 and np.allclose(back.view_hulls[0], hull)
    text = (tmp_path / "c.json").read_text().replace('"version": 1', '"version": 9')
    (tmp_path / "v9.json").write_text(text)
    with pytest.raises(CalibrationFileError, match="newer"):
        read_calibration_json(tmp_path / "v9.json")


DOC = {"mode": "eye_in_hand", "parent_frame": "tool0", "child_frame": "cam_optical", "translation_std_mm": [0.1] * 3,
       "rotation_std_deg": [0.01] * 3}
X = Transform.from_rotvec([0.3, -1.2, 2.1], [0.04, -0.025, 0.07])


def test_urdf_joint_places_the_camera_as_X() -> None:
    text = urdf_joint_text(DOC, X)
    joint = ET.fromstring(text[text.index("<joint"):])
    assert joint.get("type") == "fixed" and joint.find("parent").get("link") == "tool0"  # type: ignore[union-attr]
    assert joint.find("child").get("link") == "cam_optical"  # type: ignore[union-attr]
    origin = joint.find("origin")
    assert origin is not None
    T = transform_of_urdf_origin([float(v) for v in origin.get("xyz", "").split()],
                                 [float(v) for v in origin.get("rpy", "").split()])
    p = np.array([[0.1, 0.2, 0.3], [-0.5, 0.0, 1.0]])
    assert np.abs(T.apply(p) - X.apply(p)).max() < 1e-8


def test_static_transform_text_has_jazzys_named_arguments() -> None:
    args = shlex.split(static_transform_text(DOC, X))
    assert args[:4] == ["ros2", "run", "tf2_ros", "static_transform_publisher"]
    named = dict(zip(args[4::2], args[5::2], strict=True))
    assert named["--frame-id"] == "tool0" and named["--child-frame-id"] == "cam_optical"
    T = Transform.from_quat([float(named[k]) for k in ("--qx", "--qy", "--qz", "--qw")],
                            [float(named[k]) for k in ("--x", "--y", "--z")])
    assert np.allclose(T.matrix, X.matrix, atol=1e-9)
