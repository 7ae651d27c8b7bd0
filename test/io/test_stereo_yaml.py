"""The stereo pair's and the rig's files (io/stereo_yaml.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.rectify import rectify_pair
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.stereo_yaml import (
    RigCameraData,
    StereoData,
    StereoYamlError,
    read_rig_yaml,
    read_stereo_yaml,
    write_pair_yamls,
    write_rig_yaml,
    write_stereo_yaml,
)


def read_like_camera_calibration_parsers(path: Path) -> dict[str, object]:
    """What camera_calibration_parsers' readCalibrationYml (parse_yml.cpp) requires and reads:
    image_width, image_height, camera_matrix 3x3, rectification_matrix 3x3, projection_matrix
    3x4 (rows and cols asserted, rows*cols data), distortion_model, distortion_coefficients
    rows*cols."""
    doc = yaml.safe_load(path.read_text())
    out: dict[str, object] = {"name": doc.get("camera_name", "unknown"), "width": int(doc["image_width"]),
                              "height": int(doc["image_height"])}
    for key, (r, c) in {"camera_matrix": (3, 3), "rectification_matrix": (3, 3), "projection_matrix": (3, 4)}.items():
        m = doc[key]
        assert m["rows"] == r and m["cols"] == c
        out[key] = np.array([float(v) for v in m["data"][: r * c]]).reshape(r, c)
    d = doc["distortion_coefficients"]
    out["D"] = np.array([float(v) for v in d["data"][: d["rows"] * d["cols"]]])
    out["model"] = doc["distortion_model"]
    return out


def _pair() -> tuple[Camera, Camera, Transform]:
    left = Camera.from_params(640, 641, 322, 238, dist=[-0.2, 0.02, 0.001, -0.0005, 0.0], width=640, height=480)
    right = Camera.from_params(643, 644, 316, 243, dist=[-0.18, 0.02, -0.001, 0.0005, 0.0], width=640, height=480)
    rig = Transform.from_rotvec([0.001, 0.034, 0.002], [-0.12, -0.001, 0.005])
    return left, right, rig


def test_left_and_right_yaml_as_camera_calibration_writes_them(tmp_path: Path) -> None:
    left, right, rig = _pair()
    rect = rectify_pair(left, right, rig.R, rig.translation)
    lp, rp = write_pair_yamls(tmp_path, left, right, rect, "head")
    assert (lp.name, rp.name) == ("left.yaml", "right.yaml")
    for p, cam, R, P, side in ((lp, left, rect.R1, rect.P1, "left"), (rp, right, rect.R2, rect.P2, "right")):
        ours = read_camera_yaml(p)
        ros = read_like_camera_calibration_parsers(p)
        assert ours.camera_name == ros["name"] == f"head/{side}"
        assert np.array_equal(ours.K, cam.K) and np.array_equal(ros["camera_matrix"], cam.K)
        assert np.array_equal(ours.D, cam.D) and ros["model"] == "plumb_bob"
        assert np.array_equal(ours.R, R) and np.array_equal(ros["rectification_matrix"], R)
        assert np.array_equal(ours.P, P) and np.array_equal(ros["projection_matrix"], P)
    # the right camera's P[0, 3] = -fx' * baseline (image_geometry: baseline = -P[0, 3] / P[0, 0])
    P2 = read_camera_yaml(rp).P
    assert -P2[0, 3] / P2[0, 0] == pytest.approx(np.linalg.norm(rig.translation), rel=1e-6)


def test_stereo_yaml_round_trip(tmp_path: Path) -> None:
    left, right, rig = _pair()
    rect = rectify_pair(left, right, rig.R, rig.translation, alpha=0.5)
    d = StereoData("head/left", "head/right", "l_frame", "r_frame", 640, 480, rig, np.array([1e-3, 2e-3, 3e-4]),
                   np.array([0.01, 0.02, 0.05]), np.array([1e-3, 2e-3, 3e-4]), np.array([0.01, 0.02, 0.05]), 0.02,
                   rect)
    p = write_stereo_yaml(tmp_path / "stereo.yaml", d)
    back = read_stereo_yaml(p)
    assert np.allclose(back["rig"].matrix, rig.matrix, atol=1e-12)
    assert np.allclose(back["sigma_translation_mm"], [0.01, 0.02, 0.05])
    assert back["epipolar_rms_px"] == 0.02 and back["left_frame"] == "l_frame"
    doc = yaml.safe_load(p.read_text())
    assert doc["rectification"]["alpha"] == 0.5
    line = doc["static_transform_publisher"]
    assert "--frame-id l_frame --child-frame-id r_frame" in line
    # the line publishes the right frame's pose in the left's: the inverse of X_right = R X_left + T
    x = float(line.split("--x ")[1].split()[0])
    assert x == pytest.approx(rig.inverse().translation[0], abs=1e-6)
    bad = tmp_path / "bad.yaml"
    bad.write_text("R: [1, 2]\n")
    with pytest.raises(StereoYamlError):
        read_stereo_yaml(bad)


def test_rig_yaml_round_trip(tmp_path: Path) -> None:
    cams = [RigCameraData("front", "front_optical", "front.yaml", Transform.identity(), np.zeros(3), np.zeros(3)),
            RigCameraData("side", "side_optical", "side.yaml", Transform.from_rotvec([0, 1.2, 0], [0.1, 0, -0.05]),
                          np.array([0.001, 0.002, 0.001]), np.array([0.05, 0.04, 0.06]))]
    p = write_rig_yaml(tmp_path / "rig.yaml", cams, 12)
    back = read_rig_yaml(p)
    assert [c.name for c in back] == ["front", "side"]
    assert np.allclose(back[1].pose.matrix, cams[1].pose.matrix, atol=1e-7)
    assert np.allclose(back[1].sigma_translation_mm, [0.05, 0.04, 0.06])
    doc = yaml.safe_load(p.read_text())
    assert doc["reference_camera"] == "front" and doc["shots_used"] == 12
    assert "--frame-id front_optical --child-frame-id side_optical" in doc["cameras"][1]["static_transform_publisher"]
