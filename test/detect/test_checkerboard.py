"""Checkerboard corners against the renderer's exact corners: found on a reduced copy, refined at
full resolution as centres of point symmetry, checked against the image, in the order of
``Checkerboard.corner_points``; against OpenCV's corners (the classic detector with cornerSubPix
as its calibration tutorial runs it) corner by corner."""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
import pytest

from pascal_calib_ros.detect.checkerboard import (
    coarse_corners,
    corner_clearance,
    corner_radii,
    corner_windows,
    find_checkerboard,
    refine_corners,
    right_handed,
    saddle_grid,
)
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.detect.saddle import refine_saddles
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.sim.render import RenderedView
from pascal_calib_ros.sim.session import SessionSpec, render_session_views, session_views
from pascal_calib_ros.studies.bench import pinhole_frame
from pascal_calib_ros.targets import Checkerboard, Target, resolve_target


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


def _classic_corners(img: np.ndarray, target: Target, truth: np.ndarray) -> np.ndarray:
    """OpenCV's calibration tutorial: findChessboardCorners, then cornerSubPix with an 11x11
    half-window, 30 iterations, eps 0.001; in the truth's order (of the grid's four orders, the
    closest: OpenCV's may start at either end, with either handedness)."""
    assert target.checkerboard is not None
    nx, ny = target.checkerboard.inner_corners
    found, c = cv2.findChessboardCorners(img, (nx, ny),
                                         flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    assert found
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
    g = np.asarray(cv2.cornerSubPix(img, c, (11, 11), (-1, -1), criteria), float).reshape(ny, nx, 2)
    orders = [g, g[::-1, ::-1], g[::-1], g[:, ::-1]]
    return min((o.reshape(-1, 2) for o in orders), key=lambda o: float(np.median(np.linalg.norm(o - truth, axis=1))))


@dataclass(frozen=True)
class _TrimmedBoard(Checkerboard):
    """The last column and row of squares printed only ``keep`` of their size."""

    keep: float = 1.0

    @property
    def extent(self) -> tuple[float, float, float, float]:
        x0, y0, x1, y1 = super().extent
        cut = (1 - self.keep) * self.square_size
        return (x0, y0, x1 - cut, y1 - cut)


def _trimmed(target: Target, keep: float = 0.4, margin: float = 0.3) -> Target:
    """The target's board trimmed at its squares as in OpenCV's sample photos: the bottom row and
    right column ``keep`` of a square wide, a white strip of ``margin`` squares, the board's edge."""
    b = target.checkerboard
    assert b is not None
    t = _TrimmedBoard(b.origin, b.squares, b.square_size, b.first_square, keep=keep)
    return replace(target, sheet=(t.extent[2] + margin * b.square_size, t.extent[3] + margin * b.square_size),
                   boards=(t,))


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


@pytest.mark.parametrize(("trimmed", "width", "height", "seed"), [(False, 800, 600, 3), (True, 1280, 960, 4)])
def test_corners_as_accurate_as_opencv_classic_with_cornersubpix(plain_board: Target, trimmed: bool, width: int,
                                                                  height: int, seed: int) -> None:
    """Corner by corner against the truth, over the same corners: RMS and largest error at most
    those of OpenCV's classic detector with cornerSubPix, on the shipped board and on one trimmed
    at its squares (where that detector does well at this size)."""
    target = _trimmed(plain_board) if trimmed else plain_board
    ours, theirs = [], []
    for v in _views(target, SessionSpec(width=width, height=height, views=3, seed=seed)):
        truth = _truth(target, v)
        c = find_checkerboard(v.image, target)
        assert c is not None and np.isfinite(c).all()  # nothing rejected on a clean board
        ours.append(_errors(c, truth))
        theirs.append(_errors(_classic_corners(v.image, target, truth), truth))
    e, e_cv = np.concatenate(ours), np.concatenate(theirs)
    rms, rms_cv = np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e_cv**2))
    assert np.median(e_cv) < 0.05, np.median(e_cv)  # OpenCV's corners are good here: a comparison that can fail
    assert rms <= rms_cv and e.max() <= e_cv.max(), (rms, e.max(), rms_cv, e_cv.max())
    assert rms < 0.03 and e.max() < 0.1, (rms, e.max())


def test_a_board_trimmed_at_its_squares_is_not_pulled_to_its_edge(plain_board: Target) -> None:
    """The outer squares narrower than extrapolated: cornerSubPix with windows from the squares as
    extrapolated (the detector before) is pulled towards the board's edge; point symmetry over
    half the disc on the grid's border is not."""
    target = _trimmed(plain_board)
    assert target.checkerboard is not None
    nx, ny = target.checkerboard.inner_corners
    v = _views(target, SessionSpec(width=800, height=600, views=1, seed=3))[0]
    truth = _truth(target, v).reshape(ny, nx, 2)
    start = truth + np.random.default_rng(0).normal(0, 0.5, truth.shape)
    assert np.max(np.linalg.norm(refine_corners(v.image, start) - truth, axis=2)) > 1.0
    pts, ok = saddle_grid(v.image, start)
    assert ok.all()
    assert np.max(np.linalg.norm(pts - truth, axis=2)) < 0.1


def _spoiled(img: np.ndarray, at: np.ndarray, kind: str, scale: float) -> np.ndarray:
    """``img`` with an occluding disc (grey 110, radius 0.35 ``scale``), a smudge (darkened by up
    to 60 %, Gaussian of 0.2 ``scale``) or a glare (up to +200 grey levels, Gaussian of 0.15
    ``scale``) centred at ``at`` (px)."""
    h, w = img.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    r2 = (xx - at[0]) ** 2 + (yy - at[1]) ** 2
    out = img.astype(float)
    if kind == "occluder":
        cover = np.clip(0.35 * scale - np.sqrt(r2) + 0.5, 0, 1)
        out = out * (1 - cover) + 110 * cover
    elif kind == "smudge":
        out *= 1 - 0.6 * np.exp(-r2 / (2 * (0.2 * scale) ** 2))
    else:
        out += 200 * np.exp(-r2 / (2 * (0.15 * scale) ** 2))
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def _beside(grid: np.ndarray, j: int, i: int, fraction: float) -> np.ndarray:
    """A point ``fraction`` of the corner's clearance from corner (j, i), into the square at (j, i)."""
    u, v = grid[j, i + 1] - grid[j, i], grid[j + 1, i] - grid[j, i]
    d = u / np.linalg.norm(u) + v / np.linalg.norm(v)
    return grid[j, i] + fraction * corner_clearance(grid)[j, i] * d / np.linalg.norm(d)


@pytest.mark.parametrize("kind", ["occluder", "smudge", "glare"])
@pytest.mark.parametrize("name", ["checkerboard_a4", "pascal_board_a3"])
def test_a_spoiled_corner_is_rejected_and_the_rest_of_the_board_stays(name: str, kind: str) -> None:
    target = resolve_target(name)
    assert target.checkerboard is not None
    nx, ny = target.checkerboard.inner_corners
    v = _views(target, SessionSpec(width=800, height=600, views=1, seed=3))[0]
    truth = _truth(target, v)
    grid = truth.reshape(ny, nx, 2)
    j, i = 2, 3
    img = _spoiled(v.image, _beside(grid, j, i, 0.2), kind, corner_clearance(grid)[j, i])
    clean = detect_target(v.image, target)
    assert clean.ok and clean.note == "" and np.isfinite(clean.corners).all()  # type: ignore[arg-type]
    det = detect_target(img, target)
    assert det.ok, det.reason
    assert det.corners is not None and det.corners.shape == (nx * ny, 2)
    k = j * nx + i
    assert np.isnan(det.corners[k]).all()
    assert det.note == f"1 of {nx * ny} corners rejected: not on a saddle"
    others = np.delete(np.arange(nx * ny), k)
    assert np.max(_errors(det.corners[others], truth[others])) < 0.1  # in target order, as accurate


def test_a_board_with_most_corners_spoiled_is_refused(plain_board: Target) -> None:
    """More than half of the corners smudged: the board is refused with the reason; a target with
    a ring keeps the view for the ring and says why the board is not used."""
    assert plain_board.checkerboard is not None
    nx, ny = plain_board.checkerboard.inner_corners
    v = _views(plain_board, SessionSpec(width=800, height=600, views=1, seed=3))[0]
    grid = _truth(plain_board, v).reshape(ny, nx, 2)
    img = v.image
    spoiled = [(j, i) for j in range(ny - 1) for i in range(nx - 1) if (i + j) % 3 != 2][:40]
    for j, i in spoiled:
        img = _spoiled(img, _beside(grid, j, i, 0.2), "smudge", corner_clearance(grid)[j, i])
    assert coarse_corners(img, (nx, ny)) is not None  # the board is found ...
    det = Detection(img.shape[1], img.shape[0])
    assert find_checkerboard(img, plain_board, det) is None  # ... and refused
    assert det.reason.startswith("checkerboard not used: ") and "of 70 corners are not on a saddle" in det.reason
    full = detect_target(img, plain_board)
    assert not full.ok and full.reason == det.reason


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
    """A coarse corner too far off (seen at the board's edge under strong distortion) is not on a
    saddle where its refinement ends: it is searched again from where its row and column put it."""
    v = _views(plain_board, SessionSpec(width=800, height=600, views=1, seed=3))[0]
    assert plain_board.checkerboard is not None
    nx, ny = plain_board.checkerboard.inner_corners
    truth = _truth(plain_board, v).reshape(ny, nx, 2)
    off = truth.copy()
    off[3, nx - 1] = (truth[3, nx - 1] + truth[4, nx - 1]) / 2  # halfway along the edge to the next corner
    alone = refine_saddles(v.image, off[3, nx - 1], corner_radii(off)[3, nx - 1:nx])
    assert np.linalg.norm(alone.points[0] - truth[3, nx - 1]) > 1.0  # out of reach from there
    fixed, ok = saddle_grid(v.image, off)
    assert ok.all()
    assert np.max(np.linalg.norm(fixed - truth, axis=2)) < 0.1


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
    assert np.array_equal(right_handed(grid[::-1]), grid)
    assert np.array_equal(right_handed(grid), grid)


def test_no_board_no_corners(plain_board: Target, board_target: Target) -> None:
    assert find_checkerboard(np.full((480, 640), 128, np.uint8), plain_board) is None
    ring = resolve_target("ring_a4")
    views = _views(ring, SessionSpec(width=640, height=480, views=1, seed=2))
    assert find_checkerboard(views[0].image, board_target) is None
    assert find_checkerboard(views[0].image, ring) is None  # a target without a checkerboard
