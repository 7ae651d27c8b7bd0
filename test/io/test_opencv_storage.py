"""OpenCV FileStorage export (``io/opencv_storage.py``): the file read back by ``cv2.FileStorage`` and
projected by ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` lands within 1e-6 px of our
projection over a grid spanning the whole image; the other spellings OpenCV files use read too."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from export_cases import FISHEYE, PLUMB, RATIONAL, grid_points

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.io.format_error import CalibrationFileError
from pascal_calib_ros.io.opencv_storage import camera_from_opencv_text, read_opencv_storage, write_opencv_storage


def opencv_projection(path: Path, X: np.ndarray) -> np.ndarray:
    """Project with the camera as OpenCV reads it from the file."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    K = fs.getNode("camera_matrix").mat()
    D = fs.getNode("distortion_coefficients").mat()
    fisheye = int(fs.getNode("fisheye_model").real()) == 1
    assert int(fs.getNode("image_width").real()) > 0
    fs.release()
    z = np.zeros(3)
    if fisheye:
        q, _ = cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), z, z, K, D)
    else:
        q, _ = cv2.projectPoints(X.reshape(-1, 1, 3), z, z, K, D)
    return np.asarray(q).reshape(-1, 2)


@pytest.mark.parametrize("cam", [PLUMB, RATIONAL, FISHEYE], ids=["plumb_bob", "rational_polynomial", "equidistant"])
def test_opencv_reads_what_we_wrote_and_projects_as_we_do(tmp_path: Path, cam: Camera) -> None:
    path = write_opencv_storage(tmp_path / "cam.yaml", cam, note="test")
    X = grid_points(cam)
    assert len(X) > 1500
    diff = np.abs(opencv_projection(path, X) - cam.project(X)).max()
    assert diff < 1e-6, diff
    back = read_opencv_storage(path)
    assert back.model == cam.model and (back.width, back.height) == (cam.width, cam.height)
    assert np.array_equal(back.K, cam.K) and np.array_equal(back.D, cam.D)


def test_the_models_are_told_apart_and_the_skew_refused(tmp_path: Path) -> None:
    text = write_opencv_storage(tmp_path / "f.yaml", FISHEYE).read_text()
    assert "distortion_model: equidistant" in text and "fisheye_model: 1" in text
    skewed = Camera(PLUMB.K + np.array([[0, 0.7, 0], [0, 0, 0], [0, 0, 0]]), PLUMB.D, 800, 600)
    with pytest.raises(CalibrationFileError, match="skew"):
        write_opencv_storage(tmp_path / "s.yaml", skewed)


OPENCV4_SAMPLE = """%YAML:1.0
---
calibration_time: "Mon Jan  6 10:00:00 2025"
nr_of_frames: 25
image_width: 1280
image_height: 720
flags: 0
fisheye_model: {fisheye}
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 9.1e+02, 0., 6.4e+02, 0., 9.1e+02, 3.6e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: {n}
   cols: 1
   dt: d
   data: [ {data} ]
avg_reprojection_error: 0.31
"""


def test_files_of_opencv4s_calibration_sample_read() -> None:
    plumb = camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=5, data="-0.3, 0.1, 0.001, 0.002, -0.02"))
    assert plumb.model == "plumb_bob" and plumb.width == 1280 and plumb.D[4] == -0.02
    four = camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=4, data="-0.3, 0.1, 0.001, 0.002"))
    assert four.model == "plumb_bob" and list(four.D) == [-0.3, 0.1, 0.001, 0.002, 0.0]
    fish = camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=1, n=4, data="0.02, -0.005, 0.001, -0.0002"))
    assert fish.model == "equidistant"
    fourteen = camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=14, data=", ".join(["0.1"] * 8 + ["0"] * 6)))
    assert fourteen.model == "rational_polynomial" and len(fourteen.D) == 8
    with pytest.raises(CalibrationFileError, match="thin-prism"):
        camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=12, data=", ".join(["0.1"] * 12)))
    with pytest.raises(CalibrationFileError, match="image size"):
        camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=5, data="0, 0, 0, 0, 0").replace("image_width",
                                                                                                     "w"))
    with pytest.raises(CalibrationFileError, match="camera matrix"):
        camera_from_opencv_text(OPENCV4_SAMPLE.format(fisheye=0, n=5, data="0, 0, 0, 0, 0").replace("camera_matrix",
                                                                                                     "m"))


def test_other_spellings_and_xml_read(tmp_path: Path) -> None:
    fs = cv2.FileStorage(str(tmp_path / "c.xml"), cv2.FILE_STORAGE_WRITE)
    fs.write("cameraMatrix", PLUMB.K)
    fs.write("distCoeffs", PLUMB.D.reshape(1, -1))
    fs.write("image_size", np.array([[800.0, 600.0]]))
    fs.release()
    cam = read_opencv_storage(tmp_path / "c.xml")
    assert np.array_equal(cam.K, PLUMB.K) and np.array_equal(cam.D, PLUMB.D) and cam.height == 600
    (tmp_path / "bad.yaml").write_text("%YAML:1.0\n---\ncamera_matrix: [oops\n")
    with pytest.raises(CalibrationFileError):
        read_opencv_storage(tmp_path / "bad.yaml")
