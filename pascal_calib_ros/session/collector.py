"""Collect views during a live session: accept a view only if it adds diversity, and report
coverage per axis (like ROS ``camera_calibration``'s X / Y / size / skew bars).

A view is summarised by the target's outer ellipse (the first circle): X, Y = centre / image
size, size = sqrt(area) / image diagonal, skew = 1 - b / a (tilt); a grid by all its elements:
X, Y = mean of the element centres, size = sqrt(area of their convex hull) / diagonal, skew =
1 - the median b / a of the elements. A new view is accepted if its
L1 distance to every stored view in that space exceeds ``min_distance`` (``force``: a view asked
for with the node's ``~/capture`` is stored whatever it resembles). Coverage of an axis is
(max - min) over the stored views divided by the axis' expected span, clipped to [0, 1]. Each view
may carry the robot's tool pose at its stamp (arm sessions, hand-eye calibration).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..detect import Detection
from ..geometry import Transform, ellipses_from_conics
from ..targets import Target
from .answer import Answer
from .rejection import Rejection, RejectionKind

AXES = ("x", "y", "size", "skew")
SPANS = {"x": 0.6, "y": 0.6, "size": 0.25, "skew": 0.3}

READY_COVERAGE = 0.5  # ready: every coverage axis at least half covered (the bars on ~/detections)


def view_parameters(det: Detection, board_points: np.ndarray | None = None) -> np.ndarray | None:
    """(x, y, size, skew) of a usable detection, None without a circle or (given the board's corner
    points on the sheet, ``board_points``) at least four board corners. A board's skew is that of
    the affine map of its corners, 1 - s2 / s1 of its singular values: a circle's 1 - b / a."""
    if not det.edges:
        return _board_parameters(det, board_points)
    edges = det.edges if len(det.edges) > 3 else det.edges[:1]
    par, real = ellipses_from_conics(np.array([e.conic for e in edges]))
    par = par[real]
    if not len(par):
        return None
    diag = float(np.hypot(det.width, det.height))
    a, b = np.maximum(par[:, 2], par[:, 3]), np.minimum(par[:, 2], par[:, 3])
    if len(par) == 1:
        area = float(np.pi * a[0] * b[0])
    else:
        area = float(cv2.contourArea(cv2.convexHull(par[:, :2].astype(np.float32))))
    return np.array([float(par[:, 0].mean()) / det.width, float(par[:, 1].mean()) / det.height,
                     np.sqrt(area) / diag, 1.0 - float(np.median(b / a))])


def _board_parameters(det: Detection, board_points: np.ndarray | None) -> np.ndarray | None:
    if det.corners is None or board_points is None:
        return None
    seen = np.all(np.isfinite(det.corners), 1)
    if seen.sum() < 4:
        return None
    img, obj = det.corners[seen], np.asarray(board_points, float)[seen]
    A, *_ = np.linalg.lstsq(np.c_[obj, np.ones(len(obj))], img, rcond=None)
    s = np.linalg.svd(A[:2], compute_uv=False)
    area = float(cv2.contourArea(cv2.convexHull(img.astype(np.float32))))
    return np.array([float(img[:, 0].mean()) / det.width, float(img[:, 1].mean()) / det.height,
                     np.sqrt(area) / float(np.hypot(det.width, det.height)), 1.0 - float(s[1] / s[0])])


NO_PLACE = "no circle or board corners to place the view"


def placement_points(target: Target) -> np.ndarray | None:
    """The board corners that place a view of a target without circles (None: its circles do)."""
    return None if target.circles or target.board is None else target.board.corner_points()


@dataclass
class ViewCollector:
    min_views: int = 8
    max_views: int = 40
    min_distance: float = 0.08
    views: list[Detection] = field(default_factory=list)
    params: list[np.ndarray] = field(default_factory=list)
    robot_poses: list[Transform | None] = field(default_factory=list)  # T_base_tool per view (or None)
    rejected: Counter[str] = field(default_factory=Counter)
    last_rejection: Rejection | None = None
    board_points: np.ndarray | None = None  # the target's board corners on the sheet (a board-only target)

    def offer(self, det: Detection, robot_pose: Transform | None = None, force: bool = False) -> Answer:
        """Store the view if usable and new enough (``force``: whatever it resembles) with its
        robot pose; returns (accepted, reason)."""
        if not det.ok:
            return self.reject(Rejection(RejectionKind.TARGET, det.reason))
        if self.views and (det.width, det.height) != (self.views[0].width, self.views[0].height):
            return self.reject(Rejection(RejectionKind.IMAGE_SIZE, f"image size {det.width}x{det.height} differs from "
                                         f"the session's {self.views[0].width}x{self.views[0].height}"))
        p = view_parameters(det, self.board_points)
        if p is None:
            return self.reject(Rejection(RejectionKind.NO_PLACE, NO_PLACE))
        if self.params and not force:
            d = min(float(np.sum(np.abs(p - q))) for q in self.params)
            if d < self.min_distance:
                return self.reject(Rejection(RejectionKind.TOO_SIMILAR,
                                             "too similar to a stored view (move or tilt the target)"))
        if len(self.views) >= self.max_views:
            return self.reject(Rejection(RejectionKind.STORE_FULL,
                                         f"view store full ({self.max_views} views); calibrate or reset"))
        self.views.append(det)
        self.params.append(p)
        self.robot_poses.append(robot_pose)
        return Answer(True, "accepted")

    def reject(self, why: Rejection) -> Answer:
        """Count a refusal (by its message without the per-frame figures) and answer it."""
        self.rejected[why.key] += 1
        self.last_rejection = why
        return Answer(False, why.message)

    def coverage(self) -> dict[str, float]:
        if not self.params:
            return dict.fromkeys(AXES, 0.0)
        P = np.array(self.params)
        return {a: float(min(1.0, (P[:, k].max() - P[:, k].min()) / SPANS[a])) for k, a in enumerate(AXES)}

    @property
    def ready(self) -> bool:
        """Enough views and every axis at least half covered."""
        return len(self.views) >= self.min_views and min(self.coverage().values()) >= READY_COVERAGE

    def clear(self) -> int:
        n = len(self.views)
        self.views.clear()
        self.params.clear()
        self.robot_poses.clear()
        self.rejected.clear()
        self.last_rejection = None
        return n
