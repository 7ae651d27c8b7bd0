"""Kalibr camchain (``io/kalibr_camchain.py``): radtan and equidistant entries written and read back
exactly (Kalibr does not install from PyPI: its radtan and equidistant formulas are OpenCV's, which
``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` check on the written numbers), rigs with
T_cn_cnm1, and what Kalibr cannot hold refused with the refit named."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from export_cases import FISHEYE, PLUMB, RATIONAL, grid_points

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.format_error import CalibrationFileError
from pascal_calib_ros.io.kalibr_camchain import (
    KalibrCamera,
    kalibr_cameras,
    read_kalibr_camchain,
    write_kalibr_camchain,
)

RADTAN = Camera.from_params(812.25, 815.5, 401.3, 297.7, dist=[-0.21, 0.07, 0.0008, -0.0005, 0.0], width=800,
                            height=600)


def kalibr_projection(entry: dict, X: np.ndarray) -> np.ndarray:
    """Kalibr's pinhole-radtan / pinhole-equidistant projection of the written numbers (OpenCV's formulas)."""
    fu, fv, pu, pv = entry["intrinsics"]
    K = np.array([[fu, 0, pu], [0, fv, pv], [0, 0, 1.0]])
    D = np.array(entry["distortion_coeffs"], float)
    z = np.zeros(3)
    if entry["distortion_model"] == "equidistant":
        return cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), z, z, K, D)[0].reshape(-1, 2)
    return cv2.projectPoints(X.reshape(-1, 1, 3), z, z, K, D)[0].reshape(-1, 2)


@pytest.mark.parametrize("cam", [RADTAN, FISHEYE], ids=["radtan", "equidistant"])
def test_an_entry_projects_as_we_do_and_reads_back_exactly(tmp_path: Path, cam: Camera) -> None:
    path = write_kalibr_camchain(tmp_path / "camchain.yaml", [KalibrCamera(cam, rostopic="/cam0/image_raw")], "note")
    doc = yaml.safe_load(path.read_text())
    entry = doc["cam0"]
    assert entry["camera_model"] == "pinhole" and entry["resolution"] == [cam.width, cam.height]
    assert entry["distortion_model"] == ("radtan" if cam.model == "plumb_bob" else "equidistant")
    X = grid_points(cam)
    assert np.abs(kalibr_projection(entry, X) - cam.project(X)).max() < 1e-6
    back = read_kalibr_camchain(path)[0]
    assert back.rostopic == "/cam0/image_raw" and back.T_cn_cnm1 is None
    assert back.camera.model == cam.model and np.array_equal(back.camera.K, cam.K)
    assert np.array_equal(back.camera.D, cam.D)


def test_a_rig_keeps_its_transforms(tmp_path: Path) -> None:
    T = Transform.from_rotvec([0.01, -0.02, 0.005], [-0.11, 0.002, 0.001])
    path = write_kalibr_camchain(tmp_path / "rig.yaml", [KalibrCamera(RADTAN), KalibrCamera(FISHEYE, T)])
    cams = read_kalibr_camchain(path)
    assert [c.name for c in cams] == ["cam0", "cam1"]
    assert cams[1].T_cn_cnm1 is not None and np.allclose(cams[1].T_cn_cnm1.matrix, T.matrix, atol=1e-15)


def test_what_radtan_cannot_hold_is_refused_with_the_refit_named(tmp_path: Path) -> None:
    for cam in (PLUMB, RATIONAL):
        with pytest.raises(CalibrationFileError, match="refit"):
            write_kalibr_camchain(tmp_path / "x.yaml", [KalibrCamera(cam)])
    with pytest.raises(CalibrationFileError, match="omni"):
        kalibr_cameras({"cam0": {"camera_model": "omni", "intrinsics": [0.8, 1, 1, 1, 1]}})
    with pytest.raises(CalibrationFileError, match="fov"):
        kalibr_cameras({"cam0": {"camera_model": "pinhole", "intrinsics": [1, 1, 1, 1], "resolution": [2, 2],
                                 "distortion_model": "fov", "distortion_coeffs": [0.9]}})
    with pytest.raises(CalibrationFileError, match="resolution"):
        kalibr_cameras({"cam0": {"camera_model": "pinhole", "intrinsics": [1, 1, 1, 1]}})
    none = kalibr_cameras({"cam0": {"camera_model": "pinhole", "intrinsics": [500, 500, 320, 240],
                                    "resolution": [640, 480], "distortion_model": "none", "distortion_coeffs": []}})
    assert none[0].camera.model == "plumb_bob" and not np.any(none[0].camera.D)
