"""ChArUco and AprilGrid layouts: exactly as OpenCV draws the ChArUco and Kalibr the AprilGrid."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from pascal_calib_ros.target_boards import AprilGrid, CharucoBoard, ModuleLattice
from pascal_calib_ros.targets import TargetError, load_target, parse_target, resolve_target

# the first tag36h11 codes of Kalibr's kalibr_create_target_pdf (AprilTags C++ library's table)
KALIBR_T36H11 = (0xD5D628584, 0xD97F18B49, 0xDD280910E)


def raster(lattices: tuple[ModuleLattice, ...], extent: tuple[float, float, float, float], px_per_m: float
           ) -> np.ndarray:
    """A white image of the extent with every dark module filled (module edges on whole pixels)."""
    x0, y0, x1, y1 = extent
    img = np.full((round((y1 - y0) * px_per_m), round((x1 - x0) * px_per_m)), 255, np.uint8)
    for lat in lattices:
        for x, y, w, h in lat.rectangles():
            c0, r0 = round((x - x0) * px_per_m), round((y - y0) * px_per_m)
            img[r0:r0 + round(h * px_per_m), c0:c0 + round(w * px_per_m)] = 0
    return img


@pytest.mark.parametrize("legacy", [False, True])
def test_charuco_is_drawn_as_opencv_draws_it(legacy: bool) -> None:
    board = CharucoBoard((0.0, 0.0), (7, 6), 0.035, 0.021, "DICT_5X5_100", legacy, first_id=3)
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
    cv_board = cv2.aruco.CharucoBoard((7, 6), 0.035, 0.021, d, np.arange(3, 3 + 21))
    cv_board.setLegacyPattern(legacy)
    theirs = cv_board.generateImage((7 * 35, 6 * 35), marginSize=0, borderBits=1)  # 1 px per mm
    ours = raster(board.lattices(), board.extent, 1000.0)
    assert ours.shape == theirs.shape
    assert np.array_equal(ours < 128, theirs < 128)
    np.testing.assert_allclose(board.corner_points(), np.asarray(cv_board.getChessboardCorners())[:, :2], atol=1e-12)
    objs = board.marker_corners()
    for k, obj in zip(np.asarray(cv_board.getIds()).ravel(), cv_board.getObjPoints(), strict=True):
        np.testing.assert_allclose(objs[int(k)], np.asarray(obj)[:, :2], atol=1e-12)


def test_legacy_and_current_differ_only_for_even_rows() -> None:
    even = CharucoBoard((0.0, 0.0), (5, 4), 0.03, 0.02)
    odd = CharucoBoard((0.0, 0.0), (5, 5), 0.03, 0.02)
    assert not np.array_equal(even.square_has_marker(), CharucoBoard((0.0, 0.0), (5, 4), 0.03, 0.02,
                                                                      legacy=True).square_has_marker())
    assert np.array_equal(odd.square_has_marker(), CharucoBoard((0.0, 0.0), (5, 5), 0.03, 0.02,
                                                                legacy=True).square_has_marker())
    assert not even.square_has_marker()[0, 0]  # the current pattern starts black


def kalibr_tag(code: int) -> np.ndarray:
    """(10, 10) dark modules of a tag as kalibr_create_target_pdf draws it (two-bit border; bit
    6 i + j of the code white, then the matrix turned by 180 degrees; row 0 drawn at the top)."""
    dark = np.ones((10, 10), bool)
    m = np.array([[not code & (1 << (6 * i + j)) for j in range(6)] for i in range(6)])
    dark[2:8, 2:8] = np.rot90(m, 2)
    return dark


def test_aprilgrid_tags_are_drawn_as_kalibr_draws_them() -> None:
    grid = AprilGrid((0.0, 0.0), 3, 2, 0.04, 0.3)
    tags = grid.lattices()[1]
    ids = grid.marker_ids
    for k, code in enumerate(KALIBR_T36H11):
        r, c = np.argwhere(ids == k)[0]
        assert np.array_equal(tags.bits[r, c], kalibr_tag(code)), f"tag {k}"
    assert ids[-1, 0] == 0 and ids[-1, 1] == 1 and ids[0, 0] == 3  # tag 0 bottom left, ids along x then up


def test_aprilgrid_corners_are_kalibrs_points() -> None:
    grid = AprilGrid((0.01, 0.02), 3, 2, 0.04, 0.25)
    p = grid.corner_points()
    gap, size = 0.01, 0.04
    assert p.shape == (24, 2)
    bottom = 0.02 + gap + 2 * size + gap  # tag row 0's lower edge on the sheet (y down)
    np.testing.assert_allclose(p[0], (0.01 + gap, bottom))  # point 0: tag 0's bottom-left
    np.testing.assert_allclose(p[1], (0.01 + gap + size, bottom))
    np.testing.assert_allclose(p[6], (0.01 + gap, bottom - size))  # next corner row up
    np.testing.assert_allclose(p[12], (0.01 + gap, bottom - size - gap))  # tag row 1
    np.testing.assert_allclose(grid.tag_corner_indices(4), [14, 15, 21, 20])
    x0, y0, x1, y1 = grid.extent
    assert x1 - x0 == pytest.approx(3 * size + 4 * gap) and y1 - y0 == pytest.approx(2 * size + 3 * gap)


def test_shipped_boards_load() -> None:
    charuco, april = resolve_target("charuco_a3"), resolve_target("aprilgrid_a3")
    assert isinstance(charuco.board, CharucoBoard) and charuco.board.corner_points().shape == (70, 2)
    assert isinstance(april.board, AprilGrid) and april.board.corner_points().shape == (120, 2)
    assert charuco.default_method() == "zhang" and charuco.checkerboard is None


def test_kalibr_target_yaml_is_read_as_it_is(tmp_path: Path) -> None:
    f = tmp_path / "april_6x6.yaml"
    f.write_text("target_type: 'aprilgrid' #gridtype\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n")
    t = load_target(f)
    assert isinstance(t.board, AprilGrid) and (t.board.tag_cols, t.board.tag_size) == (6, 0.088)
    assert t.sheet[0] > 6 * 0.088 * 1.3
    f.write_text("target_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\nrowSpacingMeters: 0.06\n"
                 "colSpacingMeters: 0.06\n")
    cb = load_target(f).checkerboard
    assert cb is not None and cb.inner_corners == (6, 7)
    f.write_text("target_type: 'circlegrid'\ntargetCols: 6\n")
    with pytest.raises(TargetError, match="circlegrid"):
        load_target(f)


@pytest.mark.parametrize(("change", "match"), [
    ({"dictionary": "DICT_9X9_1"}, "unknown marker dictionary"),
    ({"marker_size": 0.03}, "smaller than square_size"),
    ({"dictionary": "DICT_4X4_50", "first_id": 20}, "needs marker ids 20..63"),
    ({"legacy": "yes"}, "true or false"),
])
def test_bad_charuco_is_refused_with_the_reason(change: dict[str, object], match: str) -> None:
    f = {"type": "charuco", "origin": [0.01, 0.01], "squares": [11, 8], "square_size": 0.03, "marker_size": 0.022,
         "dictionary": "DICT_5X5_100", **change}
    with pytest.raises(TargetError, match=match):
        parse_target({"name": "b", "sheet": {"width": 0.42, "height": 0.3}, "features": [f]})


def test_bad_aprilgrid_is_refused_with_the_reason() -> None:
    f = {"type": "aprilgrid", "origin": [0.01, 0.01], "tag_cols": 6, "tag_rows": 5, "tag_size": 0.04,
         "tag_spacing": 1.5}
    with pytest.raises(TargetError, match="tag_spacing"):
        parse_target({"name": "b", "sheet": {"width": 0.42, "height": 0.3}, "features": [f]})
    f["tag_spacing"] = 0.3
    with pytest.raises(TargetError, match="off the"):
        parse_target({"name": "b", "sheet": {"width": 0.2, "height": 0.3}, "features": [f]})
