"""Checkerboard corners against the renderer's exact corners: found on a reduced copy, refined at
full resolution, in the order of ``Checkerboard.corner_points``."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pascal_calib_ros.detect.checkerboard import (
    _repaired,
    _right_handed,
    coarse_corners,
    corner_clearance,
    corner_symmetry,
    corner_windows,
    find_checkerboard,
    refine_corners,
)
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.sim.render import RenderedView
from pascal_calib_ros.sim.session import SessionSpec, render_session_views, session_views
from pascal_calib_ros.studies.bench import pinhole_frame
from pascal_calib_ros.targets import Target, resolve_target


@pytest.fixture(scope="module")
def plain_board() -> Target:
    return resolve_target("checkerboard_a4")


def _truth(target: Target, view: RenderedView) -> np.ndarray:
    """Exact image of the inner corners: the sheet points through the true pose and camera."""
    assert target.checkerboard is not None and view.pose is not None
    P = target.checkerboard.corner_points()
    X = np.c_[P, np.zeros(len(P))] @ view.pose.R.T + view.pose.t
    return view.camera.project(X)


def _views(target: Target, spec: SessionSpec) -> list[RenderedView]:
    """The session's views; without distortion through the bench's fast path (the same pixels)."""
    if spec.k1:
        return render_session_views(target, spec)[1]
    cam = spec.camera()
    out = []
    for _, pose, sensor in session_views(target, spec):
        assert pose is not None
        img = pinhole_frame(target, cam, pose, sensor)
        assert img is not None
        out.append(RenderedView(img, cam, pose, sensor, target.name))
    return out


def _errors(corners: np.ndarray | None, truth: np.ndarray) -> np.ndarray:
    assert corners is not None
    return np.linalg.norm(corners - truth, axis=1)


def _old_corners(img: np.ndarray, target: Target) -> np.ndarray:
    """What the detector did before: findChessboardCornersSB, exhaustive and accurate, full frame."""
    assert target.checkerboard is not None
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, c = cv2.findChessboardCornersSB(img, target.checkerboard.inner_corners, flags=flags)
    assert found
    return np.asarray(c, float).reshape(-1, 2)


def _best_of_both_ends(corners: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return min((corners, corners[::-1]), key=lambda c: float(np.sum((c - truth) ** 2)))


def test_corners_at_800x600_beat_the_full_frame_search(plain_board: Target) -> None:
    views = _views(plain_board, SessionSpec(width=800, height=600, views=3, seed=3))
    new, old = [], []
    for v in views:
        truth = _truth(plain_board, v)
        new.append(_errors(find_checkerboard(v.image, plain_board), truth))  # target order, no reordering
        old.append(_errors(_best_of_both_ends(_old_corners(v.image, plain_board), truth), truth))
    e_new, e_old = np.concatenate(new), np.concatenate(old)
    rms_new, rms_old = np.sqrt(np.mean(e_new**2)), np.sqrt(np.mean(e_old**2))
    assert rms_new < 0.06 and e_new.max() < 0.25, (rms_new, e_new.max())
    assert rms_new < rms_old, (rms_new, rms_old)


def test_corners_under_wide_angle_distortion(plain_board: Target) -> None:
    spec = SessionSpec(width=800, height=600, focal=485, k1=-0.43, views=1, seed=3, size_range=(0.45, 0.85),
                       tilt_range=(15, 45))
    views = _views(plain_board, spec)
    e = np.concatenate([_errors(find_checkerboard(v.image, plain_board), _truth(plain_board, v)) for v in views])
    assert np.sqrt(np.mean(e**2)) < 0.08 and e.max() < 0.4, (np.sqrt(np.mean(e**2)), e.max())


def test_5mp_board_found_on_a_reduced_copy_and_refined_at_full_resolution(board_target: Target) -> None:
    """pascal_board_a3 at 2456x2058: the search runs on a copy halved twice, the corners are as
    accurate as on a small frame, and ``detect_target`` orders them by the ring."""
    view = _views(board_target, SessionSpec(width=2456, height=2058, views=1, seed=7))[0]
    img = view.image
    truth = _truth(board_target, view)
    assert board_target.checkerboard is not None
    coarse = coarse_corners(img, board_target.checkerboard.inner_corners)
    assert coarse is not None
    assert np.median(_errors(_best_of_both_ends(coarse, truth), truth)) > 0.1  # a coarse estimate ...
    det = detect_target(img, board_target)
    assert det.ok, det.reason
    e = _errors(det.corners, truth)  # ... refined, in target order
    assert np.sqrt(np.mean(e**2)) < 0.05 and e.max() < 0.2, (np.sqrt(np.mean(e**2)), e.max())


def test_order_follows_the_squares_colours_whichever_way_the_board_is_turned(plain_board: Target) -> None:
    """Without a ring, the dark squares fix the 180 degree ambiguity (11 x 8 squares: the two ends
    differ): the board turned upside down in the image still gives corner_points' order."""
    views = _views(plain_board, SessionSpec(width=640, height=480, views=1, seed=4))
    v = views[0]
    truth = _truth(plain_board, v)
    h, w = v.image.shape
    turned = np.ascontiguousarray(v.image[::-1, ::-1])
    for img, t in ((v.image, truth), (turned, np.array([w - 1, h - 1]) - truth)):
        assert np.max(_errors(find_checkerboard(img, plain_board), t)) < 0.3


def test_board_with_ring_is_ordered_by_the_ring(board_target: Target) -> None:
    views = _views(board_target, SessionSpec(width=1024, height=768, views=3, seed=7, size_range=(0.5, 0.8)))
    for v in views:
        d = detect_target(v.image, board_target)
        assert d.ok, d.reason
        e = _errors(d.corners, _truth(board_target, v))
        assert np.sqrt(np.mean(e**2)) < 0.08 and e.max() < 0.3, (np.sqrt(np.mean(e**2)), e.max())


def test_a_corner_left_on_an_edge_is_found_again(plain_board: Target) -> None:
    """A coarse corner too far off for its window stays on an edge after cornerSubPix (seen at the
    board's edge under strong distortion): it is not symmetric there, and is searched again from
    where its row and column put it."""
    v = _views(plain_board, SessionSpec(width=800, height=600, views=1, seed=3))[0]
    assert plain_board.checkerboard is not None
    nx, ny = plain_board.checkerboard.inner_corners
    truth = _truth(plain_board, v).reshape(ny, nx, 2)
    grid = refine_corners(v.image, truth)
    assert corner_symmetry(v.image, grid).min() > 0.9
    off = grid.copy()
    off[3, nx - 1] = (grid[3, nx - 1] + grid[4, nx - 1]) / 2  # halfway along the edge to the next corner
    assert corner_symmetry(v.image, off)[3, nx - 1] < 0.5
    fixed = _repaired(v.image, off)
    assert fixed is not None
    assert np.max(np.linalg.norm(fixed - truth, axis=2)) < 0.25


def test_windows_follow_the_squares_as_seen() -> None:
    gx, gy = np.meshgrid(np.arange(8) * 40.0, np.arange(5) * 40.0)
    grid = np.stack([gx, gy], -1) + 100
    assert np.allclose(corner_clearance(grid), 40.0)
    assert np.all(corner_windows(grid) == 16)
    assert np.all(corner_windows(grid / 4) == 4)
    # squares seen at a slant: the window follows the parallelogram's height, not its sides
    sheared = grid.copy()
    sheared[..., 0] += 0.9 * sheared[..., 1]
    assert np.allclose(corner_clearance(sheared), 40.0 / np.hypot(1, 0.9))
    # a mirrored order is turned back; a right-handed one is kept
    assert np.array_equal(_right_handed(grid[::-1]), grid)
    assert np.array_equal(_right_handed(grid), grid)


def test_no_board_no_corners(plain_board: Target, board_target: Target) -> None:
    assert find_checkerboard(np.full((480, 640), 128, np.uint8), plain_board) is None
    ring = resolve_target("ring_a4")
    views = _views(ring, SessionSpec(width=640, height=480, views=1, seed=2))
    assert find_checkerboard(views[0].image, board_target) is None
    assert find_checkerboard(views[0].image, ring) is None  # a target without a checkerboard
