"""Rectification of a calibrated pair (geometry/rectify.py) through the files a ROS consumer
reads: left.yaml / right.yaml -> cv2.initUndistortRectifyMap (cv2.fisheye. for equidistant) ->
the same 3D point on the same row."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from rig_sessions import GRID, calibrated, rendered

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.conic import conic_image_of_circle
from pascal_calib_ros.geometry.rectify import (
    RectificationError,
    horizontal_tangent_rows,
    rectified_pixels,
    rectify_pair,
)
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.stereo_yaml import write_pair_yamls
from pascal_calib_ros.sim.rig import stereo_pair
from pascal_calib_ros.targets import resolve_target


def _maps(info) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """The maps a ROS consumer builds from a CameraInfo YAML."""
    size = (info.width, info.height)
    if info.distortion_model == "equidistant":
        return cv2.fisheye.initUndistortRectifyMap(info.K, info.D.reshape(4, 1), info.R, info.P, size, cv2.CV_32FC1)
    return cv2.initUndistortRectifyMap(info.K, info.D, info.R, info.P, size, cv2.CV_32FC1)


def _lookup(mx: np.ndarray, my: np.ndarray, q: np.ndarray) -> np.ndarray:
    x, y = q[:, :1].astype(np.float32), q[:, 1:].astype(np.float32)
    return np.c_[cv2.remap(mx, x, y, cv2.INTER_LINEAR).ravel(), cv2.remap(my, x, y, cv2.INTER_LINEAR).ravel()]


def rectified_by_maps(mx: np.ndarray, my: np.ndarray, raw: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """The rectified pixels whose map entries are the raw pixels ``raw`` (N, 2): Newton's method
    on the bilinearly interpolated maps from ``q0``."""
    q = q0.astype(float).copy()
    ex, ey = np.array([0.5, 0.0]), np.array([0.0, 0.5])
    for _ in range(8):
        r = _lookup(mx, my, q) - raw
        jx = (_lookup(mx, my, q + ex) - _lookup(mx, my, q - ex)) / 1.0
        jy = (_lookup(mx, my, q + ey) - _lookup(mx, my, q - ey)) / 1.0
        J = np.stack([jx, jy], -1)  # (N, 2, 2): d raw / d q
        q -= np.linalg.solve(J, r[:, :, None])[:, :, 0]
    return q


@pytest.mark.parametrize("which", ["pair", "fisheye"])
def test_rectified_rows_agree_through_the_written_files(tmp_path: Path, which: str) -> None:
    """Every ring centre and rim point of every shot both cameras saw (the observed field),
    projected with the TRUE cameras, lands on the same row of the two images rectified with the
    estimated left.yaml / right.yaml by OpenCV's maps: within 0.1 px."""
    s, res = rendered(which), calibrated(which)
    left, right = res.cameras[0].camera(), res.cameras[1].camera()
    E = res.extrinsics[1]
    rect = rectify_pair(left, right, E.R, E.translation)
    lp, rp = write_pair_yamls(tmp_path, left, right, rect)
    infos = [read_camera_yaml(lp), read_camera_yaml(rp)]
    maps = [_maps(i) for i in infos]
    grid = resolve_target(GRID)
    th = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    P = np.concatenate([np.c_[c.center[0] + r * np.cos(th), c.center[1] + r * np.sin(th)]
                        for c in grid.circles[::2] for r in (0.0, c.radius)])
    P = np.c_[P, np.zeros(len(P))]  # the sheet's frame, as the renders' poses
    true = [rc.camera for rc in s.spec.cameras]
    rows, n = [], 0
    for shot in range(len(s.names)):
        if not (s.seen[0, shot] and s.seen[1, shot]):
            continue
        raw = [true[c].project(s.view_pose(c, shot).apply(P)) for c in range(2)]
        q0 = [rectified_pixels(true[c], (rect.R1, rect.R2)[c], (rect.P1, rect.P2)[c], raw[c]) for c in range(2)]
        w, h = s.spec.cameras[0].camera.width, s.spec.cameras[0].camera.height
        inside = np.all([(qq[:, 0] > 5) & (qq[:, 0] < w - 6) & (qq[:, 1] > 5) & (qq[:, 1] < h - 6) for qq in q0], 0)
        q = [rectified_by_maps(*maps[c], raw[c][inside], q0[c][inside]) for c in range(2)]
        for c in range(2):  # the maps were inverted
            assert np.abs(_lookup(*maps[c], q[c]) - raw[c][inside]).max() < 1e-3
        rows.append(q[0][:, 1] - q[1][:, 1])
        n += int(inside.sum())
    d = np.concatenate(rows)
    assert n > 500
    assert np.abs(d).max() < 0.1, (np.abs(d).max(), np.sqrt(np.mean(d * d)))
    # image_geometry's baseline and P's convention
    assert infos[1].P[0, 3] == pytest.approx(-infos[1].P[0, 0] * np.linalg.norm(E.translation), rel=1e-3)
    assert infos[0].P[0, 3] == 0.0 and infos[1].P[1, 3] == pytest.approx(0.0, abs=1e-9)


def test_fisheye_rectification_is_pinhole_views_of_a_stated_field() -> None:
    left, right = stereo_pair(640, 480, lens="equidistant", focal=190, dist=(0.02, -0.005, 0.001, -0.0002))
    E = right.pose.inverse()
    rect = rectify_pair(left.camera, right.camera, E.R, E.translation, alpha=0.0)
    assert np.isnan(rect.alpha) and "alpha does not apply" in rect.method
    assert rect.half_field_deg == pytest.approx(60.0)
    assert rect.baseline == pytest.approx(np.linalg.norm(E.translation), rel=1e-9)
    assert rect.P1[0, 0] == rect.P2[0, 0] and rect.P1[0, 2] == rect.P2[0, 2]


def test_refusals() -> None:
    a = Camera.from_params(600, 600, 320, 240, width=640, height=480)
    b = Camera.from_params(600, 600, 400, 300, width=800, height=600)
    with pytest.raises(RectificationError, match="differ in size"):
        rectify_pair(a, b, np.eye(3), [-0.1, 0, 0])
    with pytest.raises(RectificationError, match="along their viewing direction"):
        rectify_pair(a, a, np.eye(3), [0.0, 0.01, 0.3])
    with pytest.raises(RectificationError, match="alpha"):
        rectify_pair(a, a, np.eye(3), [-0.1, 0, 0], alpha=2.0)
    fish = Camera.from_params(200, 200, 320, 240, width=640, height=480, model="equidistant")
    with pytest.raises(RectificationError, match="fisheye and a non-fisheye"):
        rectify_pair(a, fish, np.eye(3), [-0.1, 0, 0])


def test_vertical_pair() -> None:
    a = Camera.from_params(600, 600, 320, 240, width=640, height=480)
    rect = rectify_pair(a, a, np.eye(3), [0.0, -0.1, 0.0])
    assert rect.vertical and rect.baseline == pytest.approx(0.1)


def test_horizontal_tangent_rows_of_a_circle_image() -> None:
    """A circle of radius 5 about (10, 20) in an affine image: tangent rows 15 and 25."""
    C = conic_image_of_circle(np.eye(3), (10.0, 20.0), 5.0)
    assert np.allclose(horizontal_tangent_rows(C), [15.0, 25.0])
