"""The guide's drawing on the ``~/detections`` picture (:func:`.overlay.draw_live_overlay`'s output):
the suggested target's outline (cyan; green once the live target matches it), and at the bottom of
the frame three lines: the match score with one hint (``match 0.62: move the target left``), the
projection sigma now against the goal, and ``DONE`` (or ``computing the next view...``); after a
view refused at a suggestion, the refusal with its reason until the next view is stored. Plain
numpy and OpenCV: no ROS; draws on the picture it is given and returns it.
"""

from __future__ import annotations

import cv2
import numpy as np

from .guide import MATCH_OVERLAP
from .guided_live import GuideView
from .overlay import BAR_FULL_BGR, DETECTED_BGR, TEXT_BGR, WAIT_BGR, _fit, _text, _unit

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
    u = _unit(h)
    thick, font_thick = max(2, round(2 * u)), max(1, round(1.6 * u))
    if len(v.outline) >= 3 and not v.done:
        poly = np.round(np.asarray(v.outline, float)).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(vis, [poly], True, MATCHED_BGR if v.matched else OUTLINE_BGR, thick, cv2.LINE_AA)
    y = h - round(12 * u)
    for text, colour in reversed(guide_lines(v)):
        _text(vis, _fit(text, width - round(20 * u), 0.55 * u, font_thick), (round(10 * u), y), 0.55 * u, colour,
              font_thick, background=(0, 0, 0))
        y -= round(28 * u)
    return picture
