"""The picture of a live collection session that the node publishes on ``~/detections``: what a
person moving the target needs to see, like ROS ``camera_calibration``'s window.

- The frame (grey, shown in colour), with the current detection drawn on it: the fitted edges
  green when usable, red with the rejection reason when not; checkerboard corners as circles;
  a marker board's markers outlined with their ids.
- The footprints of the stored views (each the convex hull of a view's feature points, see
  :func:`.diagnostics.feature_points`), tinted and outlined: the parts of the image no view has covered yet
  are the ones left untinted.
- The frame's verdict on a dark strip at the top left (``ok``, stored, or why not).
- A panel to the right of the frame (the output is wider than the frame): the four coverage
  bars of :meth:`.collector.ViewCollector.coverage` (X, Y, size, skew) filled red to yellow as
  they grow and green when full, with a tick at half (the node is ready when every axis is at
  least half covered), the view count and the state (``READY`` or what is still missing).

Line widths and fonts scale with the image height (readable at 800x600 as at 5 MP). Plain numpy
and OpenCV: no ROS, the input is never modified.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from ..detect import Detection
from ..geometry import ImageSize
from .collector import AXES, READY_COVERAGE

LABELS = {"x": "X", "y": "Y", "size": "Size", "skew": "Skew"}
# BGR colours (the tests check them)
DETECTED_BGR = (0, 200, 0)
REJECTED_BGR = (0, 0, 255)
CORNER_BGR = (255, 128, 0)
MARKER_BGR = (0, 220, 255)  # yellow: a marker board's markers and their ids
FOOTPRINT_BGR = (255, 0, 255)  # magenta: stands apart from the green / red edges and blue corners
FOOTPRINT_ALPHA = 0.3
BAR_FULL_BGR = (0, 255, 0)
BAR_EMPTY_BGR = (70, 70, 70)
PANEL_GREY = 32
PANEL_BGR = (PANEL_GREY,) * 3
TEXT_BGR = (235, 235, 235)
WAIT_BGR = (0, 190, 255)  # amber: what is still missing
PANEL_WIDTH = 200  # px at 600 px of image height, scaled with the height
REFERENCE_HEIGHT = 600.0


def bar_colour(fraction: float) -> tuple[int, int, int]:
    """camera_calibration's bar colour: red through orange to yellow while filling, green when full."""
    if fraction >= 1.0:
        return BAR_FULL_BGR
    return (0, round(255 * max(0.0, fraction)), 255)


def unit_scale(height: int) -> float:
    """The scale of lines, fonts and the panel's layout: 1 at 600 px of image height (at least 0.6,
    so that the panel's content fits a 240 px frame and stays legible)."""
    return max(height, 360) / REFERENCE_HEIGHT


def panel_width(height: int) -> int:
    """Width in px of the panel right of a frame of this height."""
    return round(PANEL_WIDTH * unit_scale(height))


def _to_grey8(img: np.ndarray) -> np.ndarray:
    """Grey (or BGR) uint8 / uint16 -> uint8 of the same channels; 16-bit data is scaled by its bit
    depth (a 12-bit camera in mono16 is not shown almost black). May return ``img`` itself."""
    if img.dtype == np.uint8:
        return img
    top = float(img.max()) if img.size else 0.0
    depth = max(8, int(np.ceil(np.log2(top + 1)))) if top > 0 else 8
    return np.asarray(cv2.convertScaleAbs(img, alpha=255.0 / (2**depth - 1)))


def draw_text(canvas: np.ndarray, text: str, org: tuple[int, int], scale: float, colour: tuple[int, int, int],
          thickness: int, background: tuple[int, int, int] | None = None) -> int:
    """Put text with its baseline at ``org`` (on a filled box if ``background``); returns its height."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    (w, h), base = cv2.getTextSize(text, font, scale, thickness)
    if background is not None:
        pad = max(2, h // 4)
        cv2.rectangle(canvas, (org[0] - pad, org[1] - h - pad), (org[0] + w + pad, org[1] + base + pad),
                      background, -1)
    cv2.putText(canvas, text, org, font, scale, colour, thickness, cv2.LINE_AA)
    return h + base


def fit_text(text: str, width: int, scale: float, thickness: int) -> str:
    """``text``, shortened with "..." until it is at most ``width`` px wide."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    if cv2.getTextSize(text, font, scale, thickness)[0][0] <= width:
        return text
    lo, hi = 0, len(text)  # the longest prefix that fits with the ellipsis
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if cv2.getTextSize(text[:mid] + "...", font, scale, thickness)[0][0] <= width:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo] + "..."


def bar_rects(size: ImageSize) -> dict[str, tuple[int, int, int, int]]:
    """(x0, y0, x1, y1) of each coverage bar in the output of :func:`draw_live_overlay` for a
    frame of ``width`` x ``height`` (the full bar; the fill starts at x0)."""
    width, height = size
    u = unit_scale(height)
    pw = panel_width(height)
    margin = round(12 * u)
    x0, x1 = width + margin, width + pw - margin
    rects = {}
    for i, axis in enumerate(AXES):
        y0 = round((48 + 58 * i) * u)
        rects[axis] = (x0, y0, x1, y0 + max(4, round(16 * u)))
    return rects


def _draw_footprints(vis: np.ndarray, footprints: Sequence[np.ndarray], thick: int) -> None:
    """The stored views' footprints: tinted inside (one blend over their bounding box), outlined."""
    h, w = vis.shape[:2]
    polys = [np.round(np.asarray(f, float).reshape(-1, 2)).astype(np.int32) for f in footprints if len(f) >= 3]
    if not polys:
        return
    pts = np.concatenate(polys)
    bx0, by0 = np.clip(pts.min(0), 0, [w - 1, h - 1])
    bx1, by1 = np.clip(pts.max(0) + 1, 1, [w, h])
    if bx1 > bx0 and by1 > by0:
        mask = np.zeros((by1 - by0, bx1 - bx0), np.uint8)
        shift = np.array([bx0, by0], np.int32)
        for poly in polys:  # one by one: fillPoly would leave the overlaps of several out (even-odd)
            cv2.fillPoly(mask, [(poly - shift).reshape(-1, 1, 2)], 255)
        roi = vis[by0:by1, bx0:bx1]
        tint = np.empty_like(roi)
        cv2.rectangle(tint, (0, 0), (tint.shape[1], tint.shape[0]), FOOTPRINT_BGR, -1)
        blended = cv2.addWeighted(roi, 1.0 - FOOTPRINT_ALPHA, tint, FOOTPRINT_ALPHA, 0.0)
        cv2.copyTo(blended, mask, roi)
    cv2.polylines(vis, [poly.reshape(-1, 1, 2) for poly in polys], True, FOOTPRINT_BGR, thick)


def _draw_markers(vis: np.ndarray, det: Detection, thick: int, u: float) -> None:
    """A marker board's markers used: their outlines and ids (yellow)."""
    if det.marker_ids is None or det.marker_corners is None:
        return
    quads = [np.round(c).astype(np.int32).reshape(-1, 1, 2) for c in det.marker_corners]
    cv2.polylines(vis, quads, True, MARKER_BGR, thick)
    for k, c in zip(det.marker_ids, det.marker_corners, strict=True):
        x, y = np.mean(c, axis=0)
        draw_text(vis, str(int(k)), (round(x - 6 * u), round(y + 5 * u)), 0.4 * u, MARKER_BGR, thick)


def _draw_detection(vis: np.ndarray, det: Detection | None, verdict: str | None, verdict_ok: bool | None,
                    u: float) -> None:
    """The frame's detection (ellipses, corners) and its line of text."""
    w = vis.shape[1]
    thick, font_thick = max(1, round(u)), max(1, round(1.6 * u))
    ok = det is not None and det.ok
    if det is not None:
        colour = DETECTED_BGR if det.ok else REJECTED_BGR
        edge_thick = max(2, round(1.5 * u))  # stands out on the tinted footprints
        for e in det.edges:
            cv2.polylines(vis, [np.round(e.points).astype(np.int32).reshape(-1, 1, 2)], True, colour, edge_thick)
        _draw_markers(vis, det, thick, u)
        if det.corners is not None:
            r = max(3, round(3 * u))
            for x, y in np.asarray(det.corners, float).reshape(-1, 2):
                if np.isfinite(x) and np.isfinite(y):
                    cv2.circle(vis, (round(x), round(y)), r, CORNER_BGR, thick)
    if verdict is None:
        verdict = "no frame" if det is None else ("ok" if det.ok else det.reason)
    good = ok if verdict_ok is None else verdict_ok
    verdict = fit_text(verdict, w - round(20 * u), 0.6 * u, font_thick)
    draw_text(vis, verdict, (round(10 * u), round(28 * u)), 0.6 * u, DETECTED_BGR if good else REJECTED_BGR,
          font_thick, background=(0, 0, 0))


def state_origin(size: ImageSize) -> tuple[int, int]:
    """(x, y) of the panel's state lines (the view count, then READY or what is missing) below the
    coverage bars, in the output of :func:`draw_live_overlay` for a ``width`` x ``height`` frame."""
    height = size.height
    return bar_rects(size)["x"][0], round((48 + 58 * len(AXES) + 10) * unit_scale(height))


def _draw_panel(out: np.ndarray, w: int, coverage: Mapping[str, float], views: int, min_views: int, ready: bool,
                u: float) -> None:
    """The panel right of the frame (``w`` its width): coverage bars, view count, state."""
    h = out.shape[0]
    thick, font_thick = max(1, round(u)), max(1, round(1.6 * u))
    small = 0.5 * u
    for axis, (x0, y0, x1, y1) in bar_rects(ImageSize(w, h)).items():
        p = float(np.clip(coverage.get(axis, 0.0), 0.0, 1.0))
        draw_text(out, f"{LABELS[axis]} {int(100 * p)}%", (x0, y0 - round(6 * u)), small, TEXT_BGR, font_thick)
        cv2.rectangle(out, (x0, y0), (x1 - 1, y1 - 1), BAR_EMPTY_BGR, -1)
        fill = x0 + round(p * (x1 - x0))
        if fill > x0:
            cv2.rectangle(out, (x0, y0), (fill - 1, y1 - 1), bar_colour(p), -1)
        half = x0 + round(READY_COVERAGE * (x1 - x0))
        cv2.rectangle(out, (half - thick // 2, y0 - max(2, round(4 * u))), (half + (thick - 1) // 2, y0 - 1),
                      TEXT_BGR, -1)
    x0, y = state_origin(ImageSize(w, h))
    draw_text(out, f"views {views}/{min_views}", (x0, y), 0.6 * u, TEXT_BGR, font_thick)
    y += round(34 * u)
    if ready:
        draw_text(out, "READY", (x0, y), 0.8 * u, BAR_FULL_BGR, font_thick + 1)
        y += round(26 * u)
        draw_text(out, "call ~/calibrate", (x0, y), small, TEXT_BGR, font_thick)
    elif views < min_views:
        draw_text(out, f"need {min_views - views} more", (x0, y), 0.6 * u, WAIT_BGR, font_thick)
    else:
        short = [LABELS[a] for a in AXES if coverage.get(a, 0.0) < READY_COVERAGE]
        draw_text(out, "cover more:", (x0, y), 0.6 * u, WAIT_BGR, font_thick)
        y += round(26 * u)
        draw_text(out, " ".join(short) or "-", (x0, y), small, WAIT_BGR, font_thick)


def draw_live_overlay(img: np.ndarray, det: Detection | None, footprints: Sequence[np.ndarray],
                      coverage: Mapping[str, float], views: int, min_views: int, ready: bool,
                      verdict: str | None = None, verdict_ok: bool | None = None) -> np.ndarray:
    """The ``~/detections`` picture (module docstring): a new BGR uint8 image of the frame's height
    and its width plus :func:`panel_width`.

    ``img``: the grey frame (uint8 or uint16; a BGR frame is accepted too); ``det``: the frame's
    detection (None: none drawn); ``footprints``: the stored views' outlines, (K, 2) pixel
    polygons; ``coverage``: axis -> fraction in [0, 1]; ``views`` stored of ``min_views`` needed;
    ``ready``: the collector's verdict. ``verdict``: the frame's line of text (default: ``ok`` or
    the detection's rejection reason), drawn green if ``verdict_ok`` (default: the detection is
    usable), else red.
    """
    frame = _to_grey8(np.asarray(img))
    h, w = frame.shape[:2]
    u = unit_scale(h)
    pw = panel_width(h)
    # frame and panel in one new image (cv2 is several times faster than numpy at filling BGR)
    if frame.ndim == 2:
        out = cv2.cvtColor(cv2.copyMakeBorder(frame, 0, 0, 0, pw, cv2.BORDER_CONSTANT, value=PANEL_GREY),
                           cv2.COLOR_GRAY2BGR)
    else:
        out = cv2.copyMakeBorder(frame[:, :, :3], 0, 0, 0, pw, cv2.BORDER_CONSTANT, value=(PANEL_GREY,) * 3)
    vis = out[:, :w]  # a view: drawing on it draws on ``out``
    _draw_footprints(vis, footprints, max(1, round(u)))
    _draw_detection(vis, det, verdict, verdict_ok, u)
    _draw_panel(out, w, coverage, views, min_views, ready, u)
    return out
