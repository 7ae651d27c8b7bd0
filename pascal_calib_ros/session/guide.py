"""The state of a guided session, ROS-free: what to show next, how well the live target matches
it, and whether the accuracy asked for is reached. The node holds one :class:`GuideState`.

- Until a calibration exists (fewer than 3 views) the suggestions are fixed bootstrap views
  (:func:`..analysis.candidates.bootstrap_placements`) drawn with a guessed camera; then they are
  ranked by their predicted effect (:func:`..analysis.view_ranking.suggest_views`).
- A live detection matches the suggestion when the overlap (intersection over union) of the
  target's outline as detected and as suggested is at least :data:`MATCH_OVERLAP` (0.85, the
  threshold of pose_calib, Rojtberg & Kuijper 2018); a hint line says what to change first.
- **Done** is decided by :meth:`GuideState.update` on the real projection uncertainty of the
  recalibrated views, never on a prediction; a view the detector refused is never among them.
- A suggestion whose view the detector refused (:meth:`GuideState.refuse`) is avoided for the rest
  of the session: its placement joins :attr:`GuideState.avoided`, no suggestion in its
  neighbourhood (not :func:`..analysis.view_ranking.distinct` from it: the same test that keeps a
  captured view from being suggested again) is offered, and the next one is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..analysis import (
    Placement,
    RankedView,
    bootstrap_placements,
    distinct_from_all,
    outline_points,
    place,
    suggest_views,
)
from ..calibrate import RefineResult
from ..detect import Detection
from ..geometry import Camera, ImageSize, Transform
from ..targets import Target

MATCH_OVERLAP = 0.85
RASTER = 4  # outlines are compared on a copy of the image this many times smaller


def outline_polygon(target: Target, camera: Camera, pose: Transform) -> np.ndarray:
    """Convex hull (K, 2) in pixels of the target's features at ``pose`` (camera_T_target)."""
    P = outline_points(target)
    X = pose.apply(np.c_[P, np.zeros(len(P))])
    uv = camera.project(X)
    uv = uv[np.all(np.isfinite(uv), 1)]
    if len(uv) < 3:
        return np.zeros((0, 2))
    return cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2).astype(float)


def detection_polygon(det: Detection) -> np.ndarray:
    """Convex hull (K, 2) of a detection's edge points and corners."""
    parts = [np.asarray(e.points, float).reshape(-1, 2) for e in det.edges]
    if det.corners is not None:
        parts.append(np.asarray(det.corners, float).reshape(-1, 2))
    pts = np.concatenate(parts) if parts else np.zeros((0, 2))
    if len(pts) < 3:
        return np.zeros((0, 2))
    return cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2).astype(float)


def overlap(a: np.ndarray, b: np.ndarray, size: ImageSize) -> float:
    """Intersection over union of two convex polygons (pixels) inside the image."""
    width, height = size
    if len(a) < 3 or len(b) < 3:
        return 0.0
    w, h = max(width // RASTER, 1), max(height // RASTER, 1)
    ma, mb = np.zeros((h, w), np.uint8), np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(ma, np.round(a / RASTER).astype(np.int32), 1)
    cv2.fillConvexPoly(mb, np.round(b / RASTER).astype(np.int32), 1)
    union = int(np.count_nonzero(ma | mb))
    return float(np.count_nonzero(ma & mb)) / union if union else 0.0


def hint(live: np.ndarray, wanted: np.ndarray, width: int, live_pose: Transform | None = None,
         wanted_pose: Transform | None = None) -> str:
    """One line for the person: the largest difference first (position, distance, then tilt when
    both poses are known). Directions are the image's (left = towards column 0)."""
    if len(live) < 3:
        return "show the whole target"
    ca, cb = live.mean(0), wanted.mean(0)
    d = cb - ca
    area_a, area_b = cv2.contourArea(live.astype(np.float32)), cv2.contourArea(wanted.astype(np.float32))
    scale = np.sqrt(area_b / max(area_a, 1e-9))
    if np.hypot(*d) > 0.06 * width:
        if abs(d[0]) >= abs(d[1]):
            return "move the target right" if d[0] > 0 else "move the target left"
        return "move the target down" if d[1] > 0 else "move the target up"
    if abs(np.log(scale)) > np.log(1.12):
        return "bring the target closer" if scale > 1 else "move the target farther away"
    if live_pose is not None and wanted_pose is not None:
        dn = wanted_pose.R[:, 2] - live_pose.R[:, 2]  # the sheet's normal points away from the camera
        if max(abs(dn[0]), abs(dn[1])) > np.sin(np.radians(6)):
            if abs(dn[0]) >= abs(dn[1]):
                return "turn the right side away" if dn[0] > 0 else "turn the left side away"
            return "tilt the bottom away" if dn[1] > 0 else "tilt the top away"
    return "match the outline"


@dataclass(frozen=True)
class Match:
    """How a live detection compares with the suggestion."""

    overlap: float
    matched: bool  # overlap >= MATCH_OVERLAP
    hint: str


@dataclass
class GuideState:
    """A guided session (module docstring). ``camera_guess``: the camera used to draw bootstrap
    suggestions before a calibration exists (a previous calibration, or a nominal one)."""

    target: Target
    camera_guess: Camera
    goal_sigma_px: float = 0.1
    n: int = 5
    suggestions: list[RankedView] = field(default_factory=list)
    index: int = 0
    sigma_px: float = float("nan")  # worst projection sigma over the image of the captured views (real)
    camera: Camera | None = None
    avoided: list[Placement] = field(default_factory=list)  # suggestions whose views the detector refused
    refusals: list[str] = field(default_factory=list)  # one line per refused suggestion

    def __post_init__(self) -> None:
        if not self.suggestions:
            self._bootstrap()

    @property
    def done(self) -> bool:
        """The real projection uncertainty of the captured views reaches the goal."""
        return bool(np.isfinite(self.sigma_px) and self.sigma_px <= self.goal_sigma_px)

    @property
    def current(self) -> RankedView | None:
        return self.suggestions[self.index] if self.suggestions else None

    def skip(self) -> RankedView | None:
        """Move on to the next suggestion (round robin)."""
        if self.suggestions:
            self.index = (self.index + 1) % len(self.suggestions)
        return self.current

    def _allowed(self, views: list[RankedView]) -> list[RankedView]:
        """``views`` without those in the neighbourhood of an avoided placement."""
        if not views or not self.avoided:
            return views
        w, h = self.camera_guess.width, self.camera_guess.height
        keep = distinct_from_all([v.placement for v in views], self.avoided, ImageSize(w, h))
        return [v for v, k in zip(views, keep, strict=True) if k]

    def _bootstrap(self) -> None:
        cam = self.camera_guess
        self.suggestions = self._allowed([RankedView(place(self.target, cam, p), p, float("nan"), np.zeros((0, 0)))
                                          for p in bootstrap_placements(cam, self.target)])
        self.index = 0

    def refuse(self, reason: str) -> str:
        """The view taken at the current suggestion was refused by the detector (``reason``): avoid
        its neighbourhood from now on and move on to the next suggestion. Returns the line that says
        so ("" without a suggestion). The list may run empty: the next :meth:`update` ranks again."""
        s = self.current
        if s is None:
            return ""
        p = s.placement
        line = (f"refused ({reason}) at suggestion centre ({p.pixel[0]:.0f}, {p.pixel[1]:.0f}) px, "
                f"{p.distance:.2f} m, tilt {p.tilt_deg:.0f} deg: its neighbourhood is not suggested again")
        self.avoided.append(p)
        self.refusals.append(line)
        before = self.index
        self.suggestions = self._allowed(self.suggestions)
        self.index = min(before, len(self.suggestions) - 1) if self.suggestions else 0
        return line

    def update(self, refinement: RefineResult | None, size: ImageSize, n_views: int) -> None:
        """After a view was captured: with a calibration (``refinement``, of ``n_views`` >= 3
        views) the real sigma and the ranked suggestions; without, the next bootstrap view, or,
        when an earlier calibration ranked views and this recalibration failed, the next of those
        ranked views (never a bootstrap view already taken); the sigma is then unknown."""
        width, height = size
        if (refinement is None or refinement.covariance is None) and n_views > 3 and self.camera is not None \
                and len(self.suggestions) > 1:
            self.suggestions = self._allowed(self.suggestions[:self.index] + self.suggestions[self.index + 1:])
            self.index = 0
            self.sigma_px = float("nan")
            if self.suggestions:
                return
        if refinement is None or refinement.covariance is None or n_views < 3:
            self.camera = None
            self._bootstrap()
            self.index = max(0, min(n_views, len(self.suggestions) - 1))
            self.sigma_px = float("nan")
            return
        s = suggest_views(refinement, self.target, ImageSize(width, height), self.n, avoid=self.avoided)
        self.sigma_px, self.camera, self.suggestions, self.index = s.sigma_px, s.camera, s.suggestions, 0

    def outline(self) -> np.ndarray:
        """The suggested target's outline (K, 2) in pixels, drawn with the current camera."""
        s = self.current
        if s is None:
            return np.zeros((0, 2))
        return outline_polygon(self.target, self.camera or self.camera_guess, s.pose)

    def match(self, det: Detection, live_pose: Transform | None = None) -> Match:
        """Compare a live detection with the suggestion (module docstring)."""
        s = self.current
        if s is None or not det.ok:
            return Match(0.0, False, "show the whole target" if s is not None else "")
        want, live = self.outline(), detection_polygon(det)
        ov = overlap(live, want, det.size)
        ok = ov >= MATCH_OVERLAP
        return Match(ov, ok, "hold still" if ok else hint(live, want, det.width, live_pose, s.pose))
