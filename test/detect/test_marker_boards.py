"""ChArUco and AprilGrid corners: right ids, edge-accurate, partial views counted, bad views refused."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from pascal_calib_ros.detect import detect_target
from pascal_calib_ros.detect.marker_boards import MIN_CORNERS, charuco_detector
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.sim.render import Pose, RenderedView, SensorModel, look_at_pose, render_view
from pascal_calib_ros.target_boards import CharucoBoard
from pascal_calib_ros.targets import Target, resolve_target

CAMERA = Camera.from_params(700, 700, 321.0, 238.0, dist=[-0.25, 0.06, 0.0005, -0.0003, 0.0], width=640, height=480)
FISHEYE = Camera.from_params(230, 230, 322.0, 241.0, dist=[0.02, -0.005, 0.001, -0.0002], width=640, height=480,
                             model="equidistant")


def truth(target: Target, cam: Camera, pose: Pose) -> np.ndarray:
    assert target.board is not None
    P = target.board.corner_points()
    return cam.project((pose.R @ np.c_[P, np.zeros(len(P))].T).T + pose.t)


@cache
def view(name: str, pixel: tuple[float, float] = (320, 240), size: float = 0.8, tilt: float = 30.0,
         fisheye: bool = False, seed: int = 0) -> RenderedView:
    target, cam = resolve_target(name), FISHEYE if fisheye else CAMERA
    pose = look_at_pose(target, cam, pixel, size, tilt, 35.0, 10.0)
    return render_view(target, cam, pose, SensorModel(seed=seed))


@pytest.mark.parametrize("name", ["charuco_a3", "aprilgrid_a3"])
def test_corners_have_the_right_ids_and_edge_accuracy(name: str) -> None:
    target, v = resolve_target(name), view(name)
    det = detect_target(v.image, target)
    assert det.ok, det.reason
    assert v.pose is not None and det.corners is not None
    seen = np.isfinite(det.corners[:, 0])
    assert seen.mean() > 0.8
    err = np.linalg.norm(det.corners[seen] - truth(target, CAMERA, v.pose)[seen], axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.04 and err.max() < 0.15
    assert det.marker_ids is not None and len(det.marker_ids) >= 10


def test_charuco_corners_beat_opencvs_on_the_same_image() -> None:
    target, v = resolve_target("charuco_a3"), view("charuco_a3")
    assert isinstance(target.board, CharucoBoard) and v.pose is not None
    corners, ids, _, _ = charuco_detector(target.board).detectBoard(v.image)
    ids = np.asarray(ids).ravel()
    t = truth(target, CAMERA, v.pose)
    theirs = np.linalg.norm(np.asarray(corners).reshape(-1, 2) - t[ids], axis=1)
    det = detect_target(v.image, target)
    assert det.corners is not None
    both = ids[np.isfinite(det.corners[ids, 0])]
    ours = np.linalg.norm(det.corners[both] - t[both], axis=1)
    assert np.sqrt(np.mean(ours**2)) < 0.6 * np.sqrt(np.mean(theirs**2))


@pytest.mark.parametrize("name", ["charuco_a3", "aprilgrid_a3"])
def test_a_view_hanging_out_of_the_frame_counts(name: str) -> None:
    target = resolve_target(name)
    v = view(name, pixel=(40, 60), size=1.1, tilt=20.0)
    assert v.pose is not None
    t = truth(target, CAMERA, v.pose)
    inside = (t[:, 0] > 3) & (t[:, 0] < 636) & (t[:, 1] > 3) & (t[:, 1] < 476)
    assert 0.1 < inside.mean() < 0.7  # the board is cut by the border
    det = detect_target(v.image, target)
    assert det.ok, det.reason
    assert det.corners is not None
    seen = np.isfinite(det.corners[:, 0])
    assert seen.sum() >= max(MIN_CORNERS, 0.6 * inside.sum()) and not (seen & ~inside).any()
    err = np.linalg.norm(det.corners[seen] - t[seen], axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.12


def test_aprilgrid_through_a_fisheye() -> None:
    target = resolve_target("aprilgrid_a3")
    v = view("aprilgrid_a3", pixel=(150, 150), size=0.7, tilt=25.0, fisheye=True)
    det = detect_target(v.image, target)
    assert det.ok, det.reason
    assert det.corners is not None and v.pose is not None
    seen = np.isfinite(det.corners[:, 0])
    err = np.linalg.norm(det.corners[seen] - truth(target, FISHEYE, v.pose)[seen], axis=1)
    assert seen.sum() >= 40 and np.sqrt(np.mean(err**2)) < 0.1


@pytest.mark.parametrize("name", ["charuco_a3", "aprilgrid_a3"])
def test_a_mirrored_board_is_refused_with_the_reason(name: str) -> None:
    det = detect_target(np.ascontiguousarray(view(name).image[:, ::-1]), resolve_target(name))
    assert not det.ok and "mirrored" in det.reason


def test_markers_of_another_board_are_refused_with_the_reason() -> None:
    target = resolve_target("charuco_a3")
    assert isinstance(target.board, CharucoBoard)
    other = replace(target, boards=(replace(target.board, first_id=44),))  # ids 44..87: none printed
    det = detect_target(view("charuco_a3").image, other)
    assert not det.ok and "not on this board" in det.reason


def test_two_boards_in_view_are_refused_with_the_reason() -> None:
    target = resolve_target("aprilgrid_a3")
    cam = Camera.from_params(1050, 1050, 480, 360, width=960, height=720)
    a, b = (render_view(target, cam, look_at_pose(target, cam, (u, 360), 0.45, 20.0, 0.0, 0.0),
                        SensorModel(seed=1)).image for u in (250, 710))
    twice = np.minimum(a, b)  # two copies of the board in one frame
    det = detect_target(twice, target)
    assert not det.ok and "more than once" in det.reason and "two boards" in det.reason


def test_an_occluded_corner_is_left_out_and_the_rest_measured() -> None:
    target, v = resolve_target("charuco_a3"), view("charuco_a3")
    assert v.pose is not None
    t = truth(target, CAMERA, v.pose)
    img = v.image.copy()
    x, y = np.round(t[30]).astype(int)
    img[y - 1:y + 6, x - 1:x + 6] = 40  # a smudge over one corner
    det = detect_target(img, target)
    assert det.ok and det.corners is not None
    assert not np.isfinite(det.corners[30, 0]) or np.linalg.norm(det.corners[30] - t[30]) < 0.5
    assert np.isfinite(det.corners[:, 0]).sum() > 50


def test_a_sliver_of_the_board_is_refused_with_the_reason() -> None:
    det = detect_target(view("charuco_a3", pixel=(-150, 240), size=1.0, tilt=10.0).image, resolve_target("charuco_a3"))
    assert not det.ok and ("corners" in det.reason or "marker" in det.reason)
