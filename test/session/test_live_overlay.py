import numpy as np
import pytest

from pascal_calib_ros.detect.detection import CircleEdge, Detection, feature_points
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.image_field import view_hulls
from pascal_calib_ros.session.collector import AXES, ViewCollector
from pascal_calib_ros.session.overlay import (
    BAR_EMPTY_BGR,
    BAR_FULL_BGR,
    DETECTED_BGR,
    FOOTPRINT_ALPHA,
    FOOTPRINT_BGR,
    MARKER_BGR,
    PANEL_BGR,
    REJECTED_BGR,
    WAIT_BGR,
    bar_colour,
    bar_rects,
    draw_live_overlay,
    panel_width,
)

W, H = 800, 600
SQUARE = np.array([[100.0, 100], [300, 100], [300, 300], [100, 300]])


def _circle_detection(cx: float, cy: float, r: float, reason: str = "") -> Detection:
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    pts = np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], 1)
    edge = CircleEdge(circle=0, points=pts, conic=np.zeros(6), width=1.0, rms=0.1)
    return Detection(W, H, edges=[edge], reason=reason)


def _draw(img: np.ndarray, **kw) -> np.ndarray:
    args = {"det": None, "footprints": [], "coverage": dict.fromkeys(AXES, 0.0), "views": 0, "min_views": 8,
            "ready": False, **kw}
    return draw_live_overlay(img, **args)


def _panel_below_bars(out: np.ndarray) -> np.ndarray:
    y = max(r[3] for r in bar_rects(ImageSize(W, H)).values()) + 2
    return out[y:, W:]


def _has(region: np.ndarray, bgr: tuple[int, int, int]) -> bool:
    return bool(np.all(region == np.array(bgr, np.uint8), axis=-1).any())


def test_footprints_are_tinted_and_outlined_and_the_input_is_kept() -> None:
    img = np.full((H, W), 100, np.uint8)
    before = img.copy()
    out = _draw(img, footprints=[SQUARE, SQUARE + 150])
    assert np.array_equal(img, before)
    assert out.shape == (H, W + panel_width(H), 3) and out.dtype == np.uint8
    tinted = np.round(100 * (1 - FOOTPRINT_ALPHA) + np.array(FOOTPRINT_BGR) * FOOTPRINT_ALPHA)
    assert np.abs(out[200, 200].astype(int) - tinted).max() <= 1, out[200, 200]
    assert np.array_equal(out[280, 280], out[200, 200])  # where the two overlap: tinted once
    assert np.array_equal(out[400, 400], out[200, 200])
    assert np.array_equal(out[200, 100], FOOTPRINT_BGR)  # the outline
    assert np.array_equal(out[400, 500], [100, 100, 100])  # outside every footprint
    assert np.array_equal(out[H - 1, W + 5], PANEL_BGR)


def test_footprints_of_stored_views_from_real_detections(ring_session) -> None:
    _, imgs, dets = ring_session
    c = ViewCollector(min_views=8)
    hulls = [h for d in dets if c.offer(d)[0] for h in view_hulls([feature_points(d)])]
    assert len(hulls) == len(c.views) >= 3
    out = _draw(imgs[0], det=dets[0], footprints=hulls, coverage=c.coverage(), views=len(c.views),
                ready=c.ready)
    # the centre of each footprint's hull is tinted towards magenta: blue and red above green
    for h in hulls:
        x, y = np.round(h.mean(0)).astype(int)
        b, g, r = out[y, x].astype(int)
        assert b > g and r > g, (x, y, out[y, x])
    assert _has(out[:, :W], DETECTED_BGR)  # the current frame's edges


def test_bars_fill_with_coverage_and_turn_green_when_full() -> None:
    img = np.zeros((H, W), np.uint8)
    cov = {"x": 1.0, "y": 0.0, "size": 0.5, "skew": 0.25}
    out = _draw(img, coverage=cov)
    rects = bar_rects(ImageSize(W, H))
    for x0, y0, x1, y1 in rects.values():
        assert W < x0 < x1 <= W + panel_width(H) and y1 > y0
    x0, y0, x1, y1 = rects["x"]
    assert np.all(out[y0:y1, x0:x1] == BAR_FULL_BGR)  # full: green over its whole length
    x0, y0, x1, y1 = rects["y"]
    assert np.all(out[y0:y1, x0:x1] == BAR_EMPTY_BGR)
    x0, y0, x1, y1 = rects["size"]
    ym, quarter = (y0 + y1) // 2, (x1 - x0) // 4
    assert np.array_equal(out[ym, x0 + quarter], bar_colour(0.5))
    assert np.array_equal(out[ym, x1 - quarter], BAR_EMPTY_BGR)
    assert bar_colour(0.5) != BAR_FULL_BGR and bar_colour(0.999) != BAR_FULL_BGR
    assert bar_colour(0.0) == (0, 0, 255)  # red empty, yellow nearly full (camera_calibration's colours)


def test_state_ready_or_what_is_missing() -> None:
    img = np.zeros((H, W), np.uint8)
    full = dict.fromkeys(AXES, 1.0)
    ready = _draw(img, coverage=full, views=8, ready=True)
    assert _has(_panel_below_bars(ready), BAR_FULL_BGR) and not _has(_panel_below_bars(ready), WAIT_BGR)
    waiting = _draw(img, coverage=full, views=3)
    assert _has(_panel_below_bars(waiting), WAIT_BGR) and not _has(_panel_below_bars(waiting), BAR_FULL_BGR)
    assert not np.array_equal(waiting, _draw(img, coverage=full, views=5))  # the count is drawn
    short = _draw(img, coverage={**full, "skew": 0.2}, views=8)  # enough views, not enough coverage
    assert _has(_panel_below_bars(short), WAIT_BGR)


def test_verdict_and_detection_colours() -> None:
    img = np.full((H, W), 128, np.uint8)
    ok = _draw(img, det=_circle_detection(400, 300, 100))
    assert np.array_equal(ok[300, 500], DETECTED_BGR)  # on the circle
    assert _has(ok[:60, :200], DETECTED_BGR) and not _has(ok[:60, :200], REJECTED_BGR)  # "ok"
    bad = _draw(img, det=_circle_detection(400, 300, 100, reason="cut by the image border"))
    assert np.array_equal(bad[300, 500], REJECTED_BGR)
    assert _has(bad[:60, :200], REJECTED_BGR)
    # a long reason is shortened to the frame: nothing of it spills into the panel
    long = _draw(img, det=Detection(W, H, reason="too blurred " * 30))
    assert _has(long[:60, :W], REJECTED_BGR) and not _has(long[:, W:], REJECTED_BGR)
    # the caller's verdict and colour win
    stored = _draw(img, det=_circle_detection(400, 300, 100), verdict="stored: view 3", verdict_ok=True)
    assert _has(stored[:60, :200], DETECTED_BGR) and not np.array_equal(stored, ok)


def test_a_marker_boards_markers_are_outlined_with_their_ids() -> None:
    img = np.full((H, W), 128, np.uint8)
    quad = np.array([[300.0, 200.0], [380.0, 200.0], [380.0, 280.0], [300.0, 280.0]])
    det = Detection(W, H, corners=np.array([[290.0, 190.0], [np.nan, np.nan]]), marker_ids=np.array([17]),
                    marker_corners=quad[None])
    out = _draw(img, det=det)
    assert np.array_equal(out[200, 340], MARKER_BGR) and np.array_equal(out[240, 380], MARKER_BGR)  # the outline
    assert _has(out[225:255, 320:365], MARKER_BGR)  # the id inside
    assert not _has(_draw(img, det=Detection(W, H, corners=det.corners)), MARKER_BGR)


@pytest.mark.parametrize("top", [4095, 65535])
def test_uint16_frames_are_shown_by_their_bit_depth(top: int) -> None:
    img = np.zeros((H, W), np.uint16)
    img[:, W // 2:] = top
    before = img.copy()
    out = _draw(img)
    assert np.array_equal(img, before)
    assert out.dtype == np.uint8 and np.array_equal(out[H - 10, W - 10], [255, 255, 255])
    assert np.array_equal(out[H - 10, 10], [0, 0, 0])


def test_bgr_frame_and_5mp_scale() -> None:
    bgr = np.full((H, W, 3), 60, np.uint8)
    out = _draw(bgr, footprints=[SQUARE])
    assert out.shape == (H, W + panel_width(H), 3) and np.array_equal(bgr, np.full((H, W, 3), 60, np.uint8))
    w5, h5 = 2448, 2048
    big = _draw(np.zeros((h5, w5), np.uint8), coverage=dict.fromkeys(AXES, 1.0), views=8, ready=True)
    assert big.shape == (h5, w5 + panel_width(h5), 3) and panel_width(h5) > 3 * panel_width(H)
    x0, y0, x1, y1 = bar_rects(ImageSize(w5, h5))["skew"]
    small = bar_rects(ImageSize(W, H))["skew"]
    assert y1 - y0 >= 3 * (small[3] - small[1])  # bars grow with the image
    assert np.all(big[y0:y1, x0:x1] == BAR_FULL_BGR)
    # a small frame: the panel's content still fits (the state text above the bottom)
    small = _draw(np.zeros((240, 320), np.uint8), coverage=dict.fromkeys(AXES, 1.0), views=8, ready=True)
    assert small.shape == (240, 320 + panel_width(240), 3)
    assert _has(small[max(r[3] for r in bar_rects(ImageSize(320, 240)).values()) + 2:, 320:], BAR_FULL_BGR)  # READY


def test_feature_points_take_edges_and_corners() -> None:
    det = _circle_detection(400, 300, 50)
    det.corners = np.array([[10.0, 10], [20, 10], [20, 20]])
    pts = feature_points(det)
    assert pts.shape == (203, 2) and np.array_equal(pts[-1], [20, 20])
    assert feature_points(Detection(W, H, reason="nothing")).shape == (0, 2)
