"""The guide's drawing on the ``~/detections`` picture (:func:`.overlay.draw_live_overlay`'s output):
the suggested target's outline (cyan; green once the live target matches it), and at the bottom of
the frame three lines: the match score with one hint (``match 0.62: move the target left``), the
projection sigma now against the goal, and ``DONE`` (or ``computing the next view...``); after a
view refused at a suggestion, the refusal with its reason until the next view is stored. In the
panel the guide's progress replaces the coverage verdict ("cover more: X Y", which would send the
person elsewhere than the suggestion): one bar, the goal over the real sigma (full at the goal),
below the coverage bars that stay as they are. Plain numpy and OpenCV: no ROS; draws on the
picture it is given and returns it.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry import ImageSize
from .guide import MATCH_OVERLAP
from .guided_live import GuideView
from .overlay import (
    BAR_EMPTY_BGR,
    BAR_FULL_BGR,
    DETECTED_BGR,
    PANEL_BGR,
    TEXT_BGR,
    WAIT_BGR,
    bar_colour,
    draw_text,
    fit_text,
    state_origin,
    unit_scale,
)

OUTLINE_BGR = (255, 255, 0)  # cyan: the suggestion, apart from the green / red detection and magenta footprints
MATCHED_BGR = DETECTED_BGR


def guide_lines(v: GuideView) -> list[tuple[str, tuple[int, int, int]]]:
    """The guide's lines of text (bottom of the frame) with their colours."""
    if v.computing:
        first = ("computing the next view...", WAIT_BGR)
    elif v.done:
        first = ("DONE: call ~/calibrate", BAR_FULL_BGR)
    else:
        first = (f"match {v.overlap:.2f} (need {MATCH_OVERLAP:.2f}): {v.hint or 'show the target'}",
                 MATCHED_BGR if v.matched else WAIT_BGR)
    sigma = "none yet (3 views first)" if not np.isfinite(v.sigma_px) else f"{v.sigma_px:.3f} px"
    second = (f"sigma now {sigma}, goal {v.goal_sigma_px:g} px", BAR_FULL_BGR if v.done else TEXT_BGR)
    lines = [first, second]
    if v.refused and not v.done:
        lines.append((v.refused, WAIT_BGR))
    if v.suggestion and not v.done:
        lines.append((f"next view {v.suggestion}", TEXT_BGR))
    return lines


def draw_guide(picture: np.ndarray, v: GuideView, width: int) -> np.ndarray:
    """Draw the guide on ``picture`` (BGR, the frame in its first ``width`` columns); returns it."""
    vis = picture[:, :width]
    h = vis.shape[0]
    u = unit_scale(h)
    thick, font_thick = max(2, round(2 * u)), max(1, round(1.6 * u))
    if len(v.outline) >= 3 and not v.done:
        poly = np.round(np.asarray(v.outline, float)).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(vis, [poly], True, MATCHED_BGR if v.matched else OUTLINE_BGR, thick, cv2.LINE_AA)
    _draw_progress(picture, v, width)
    y = h - round(12 * u)
    for text, colour in reversed(guide_lines(v)):
        draw_text(vis, fit_text(text, width - round(20 * u), 0.55 * u, font_thick), (round(10 * u), y), 0.55 * u,
                  colour, font_thick, background=(0, 0, 0))
        y -= round(28 * u)
    return picture


def progress(v: GuideView) -> float:
    """The guide's progress in [0, 1]: the goal over the real worst projection sigma (0 before a
    calibration, 1 once the goal is reached)."""
    if v.done:
        return 1.0
    if not np.isfinite(v.sigma_px) or v.sigma_px <= 0:
        return 0.0
    return float(np.clip(v.goal_sigma_px / v.sigma_px, 0.0, 1.0))


def _draw_progress(picture: np.ndarray, v: GuideView, width: int) -> None:
    """The panel's state lines (below the coverage bars) replaced by the guide's progress bar."""
    h = picture.shape[0]
    if picture.shape[1] <= width:
        return
    u = unit_scale(h)
    font_thick = max(1, round(1.6 * u))
    x0, y = state_origin(ImageSize(width, h))
    x1 = picture.shape[1] - (x0 - width)
    cv2.rectangle(picture, (width, y - round(24 * u)), (picture.shape[1] - 1, y + round(120 * u)), PANEL_BGR, -1)
    p = progress(v)
    draw_text(picture, f"guide {int(100 * p)}%", (x0, y), 0.6 * u, TEXT_BGR, font_thick)
    top, bottom = y + round(10 * u), y + round(30 * u)
    cv2.rectangle(picture, (x0, top), (x1 - 1, bottom), BAR_EMPTY_BGR, -1)
    if p > 0:
        cv2.rectangle(picture, (x0, top), (x0 + max(1, round(p * (x1 - x0))) - 1, bottom), bar_colour(p), -1)
    state = ("DONE: ~/calibrate" if v.done else "follow the outline")
    draw_text(picture, state, (x0, bottom + round(26 * u)), 0.5 * u, BAR_FULL_BGR if v.done else WAIT_BGR, font_thick)
