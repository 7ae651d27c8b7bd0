"""A live stereo session, ROS-free and thread-safe: what the node's stereo mode does with each pair.

The node pairs the two cameras' frames by stamp (:mod:`.frame_pairing`) and detects the target
in both; :class:`StereoSession` then decides, as the single-camera session does
(:mod:`.live`), with the same parts: each camera's view must be usable (detected whole, and still
when ``max_motion_px`` is set: one :class:`~.arm_session.StillnessGate` per camera), and a shot
is stored when it adds diversity (:class:`~.collector.ViewCollector`'s L1 distance in x, y, size,
skew) in at least one camera's image. A shot both cameras see serves both intrinsics and the rig
transform; a shot only one camera sees serves that camera's intrinsics (the answer says so); the
other camera's view is kept as a rejected detection with its reason, so the shot list is what
:func:`~..workflows.stereo.stereo_from_detections` takes (``dets[0]`` left, ``dets[1]`` right).

The session is ready when ``min_views`` shots are seen by both cameras and every coverage axis
of both cameras is at least half covered; :meth:`StereoSession.refusal` says why a calibration
cannot start yet.
"""

from __future__ import annotations

import threading
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ..detect import Detection, DetectionRefusal, feature_points
from ..geometry import view_hulls
from .answer import Answer
from .arm_session import MOVING, StillnessGate
from .collector import NO_PLACE, READY_COVERAGE, ViewCollector, view_parameters
from .frame_pairing import SIDES
from .overlay import draw_live_overlay
from .rejection import Rejection, RejectionKind, rejection_key


@dataclass
class StereoCollector:
    """The stored shots and each camera's views (for coverage and diversity)."""

    min_views: int = 8  # shots both cameras see, needed to calibrate
    max_views: int = 40  # shots kept at most
    min_distance: float = 0.08
    shots: list[tuple[Detection, Detection]] = field(default_factory=list)
    cameras: tuple[ViewCollector, ViewCollector] = field(default_factory=lambda: (ViewCollector(), ViewCollector()))
    rejected: Counter[str] = field(default_factory=Counter)  # shot-level reasons
    last_rejection: str = ""

    @property
    def both(self) -> int:
        """Shots both cameras see."""
        return sum(1 for left, right in self.shots if left.ok and right.ok)

    def coverage(self) -> tuple[dict[str, float], dict[str, float]]:
        return self.cameras[0].coverage(), self.cameras[1].coverage()

    @property
    def ready(self) -> bool:
        cov = self.coverage()
        return self.both >= self.min_views and min(min(c.values()) for c in cov) >= READY_COVERAGE

    def reject(self, reason: str) -> Answer:
        self.rejected[rejection_key(reason)] += 1
        self.last_rejection = reason
        return Answer(False, reason)

    def _is_new(self, c: int, p: np.ndarray) -> bool:
        params = self.cameras[c].params
        return not params or min(float(np.sum(np.abs(p - q))) for q in params) >= self.min_distance

    def offer(self, dets: tuple[Detection, Detection], reasons: list[Rejection | None]
              ) -> tuple[bool, str, list[Rejection | None]]:
        """Store the shot ``dets`` (left, right) if it adds diversity; ``reasons[c]`` is None when
        camera c's view is usable, else why not. Returns (stored, the shot's verdict, each
        camera's reason it was not used (None: used or usable))."""
        reasons = list(reasons)
        params: list[np.ndarray | None] = [None, None]
        for c, det in enumerate(dets):
            cam = self.cameras[c]
            if reasons[c] is None and cam.views and (det.width, det.height) != (cam.views[0].width,
                                                                                 cam.views[0].height):
                reasons[c] = Rejection(RejectionKind.IMAGE_SIZE, f"image size {det.width}x{det.height} differs from "
                                       f"the session's {cam.views[0].width}x{cam.views[0].height}")
            if reasons[c] is None:
                params[c] = view_parameters(det, cam.board_points)
                if params[c] is None:
                    reasons[c] = Rejection(RejectionKind.NO_PLACE, NO_PLACE)
            why = reasons[c]
            if why is not None:
                cam.reject(why)
        usable = [p is not None for p in params]
        if not any(usable):
            if rejection_key(str(reasons[0])) == rejection_key(str(reasons[1])):
                return (*self.reject(f"both cameras: {reasons[0]}"), reasons)
            return (*self.reject(f"neither camera has a usable view (left: {reasons[0]}; right: {reasons[1]})"),
                    reasons)
        if not any(self._is_new(c, p) for c, p in enumerate(params) if p is not None):
            return (*self.reject("too similar to a stored shot (move or tilt the target)"), reasons)
        if len(self.shots) >= self.max_views:
            return (*self.reject(f"shot store full ({self.max_views} shots); calibrate or reset"), reasons)
        kept = []
        shot = dets[0].name or dets[1].name
        for c, (det, p) in enumerate(zip(dets, params, strict=True)):
            if p is None:  # kept as a rejected view: the shot list stays aligned, its reason shown
                why_c = reasons[c]  # the detector's kind when it refused the view, else OTHER
                kind = (DetectionRefusal.SIZE_MISMATCH if why_c is not None and why_c.kind == RejectionKind.IMAGE_SIZE
                        else det.refusal)
                kept.append(Detection(det.width, det.height, name=det.name or shot, reason=str(why_c), refusal=kind))
                continue
            cam = self.cameras[c]
            cam.views.append(det)
            cam.params.append(p)
            cam.robot_poses.append(None)
            kept.append(det)
        self.shots.append((kept[0], kept[1]))
        n = len(self.shots) - 1
        if all(usable):
            return True, f"shot {n} stored (both cameras)", reasons
        c = usable.index(True)
        other = SIDES[1 - c]
        return True, (f"shot {n} stored: {SIDES[c]} only ({other}: {reasons[1 - c]}); it serves the {SIDES[c]} "
                      "camera's intrinsics"), reasons

    def restore(self, dets: tuple[Detection, Detection]) -> list[bool]:
        """Store a shot of a resumed session as it was stored (already chosen once: whatever it
        resembles, the store's limit aside); a camera's view that was not used is passed as a
        rejected detection. Returns which cameras' views are used."""
        used = []
        for c, det in enumerate(dets):
            cam = self.cameras[c]
            p = view_parameters(det, cam.board_points) if det.ok else None
            used.append(p is not None)
            if p is not None:
                cam.views.append(det)
                cam.params.append(p)
                cam.robot_poses.append(None)
        self.shots.append((dets[0], dets[1]))
        return used

    def clear(self) -> int:
        n = len(self.shots)
        self.shots.clear()
        for cam in self.cameras:
            cam.clear()
        self.rejected.clear()
        self.last_rejection = ""
        return n

    def set_limits(self, min_views: int | None, max_views: int | None, min_distance: float | None) -> None:
        self.min_views = self.min_views if min_views is None else int(min_views)
        self.max_views = self.max_views if max_views is None else int(max_views)
        self.min_distance = self.min_distance if min_distance is None else float(min_distance)
        for cam in self.cameras:
            cam.min_views, cam.max_views, cam.min_distance = self.min_views, self.max_views, self.min_distance


@dataclass(frozen=True)
class StereoSnapshot:
    """The stored shots at one moment, for a calibration."""

    shots: list[tuple[Detection, Detection]]
    min_views: int
    both: int
    views: tuple[int, int]
    rejected: dict[str, int]
    camera_rejected: tuple[dict[str, int], dict[str, int]]

    def detections(self) -> list[list[Detection]]:
        """``dets[0]`` left, ``dets[1]`` right, one per shot (what the stereo workflow takes)."""
        return [[s[0] for s in self.shots], [s[1] for s in self.shots]]


@dataclass
class PairOutcome:
    """What became of one examined pair: stored or not, the shot's verdict, each camera's line on
    the live picture (and whether it is good news), the counts, readiness and what the picture needs."""

    stored: bool
    why: str
    camera_lines: tuple[str, str]
    camera_ok: tuple[bool, bool]
    shots: int
    both: int
    ready: bool
    overlay: tuple[tuple[list[np.ndarray], list[np.ndarray]], tuple[dict[str, float], dict[str, float]], int] | None


class StereoSession:
    """The collection state of a live stereo session; every method may be called from any thread."""

    def __init__(self, min_views: int, max_views: int, min_distance: float, max_motion_px: float,
                 board_points: np.ndarray | None = None) -> None:
        self.lock = threading.Lock()
        self.collector = StereoCollector(min_views, max_views, min_distance)
        for cam in self.collector.cameras:
            cam.board_points = board_points
        self.collector.set_limits(min_views, max_views, min_distance)
        self.gates = (StillnessGate(max_motion_px), StillnessGate(max_motion_px))
        self.footprints: tuple[list[np.ndarray], list[np.ndarray]] = ([], [])

    def bad_frame(self, side: int, reason: str) -> None:
        """Count a frame that could not be converted."""
        with self.lock:
            self.collector.cameras[side].reject(Rejection(RejectionKind.BAD_FRAME, f"bad frame: {reason}"))

    def examine(self, dets: tuple[Detection, Detection], stamps_ns: tuple[int, int], drawing: bool) -> PairOutcome:
        """Apply the session's policy to one pair's detections (module docstring)."""
        reasons = []
        for c in (0, 1):
            verdict = self.gates[c].examine(dets[c], stamps_ns[c], None, 0.0)
            reasons.append(None if verdict.usable else verdict.why)
        with self.lock:
            col = self.collector
            stored, why, reasons = col.offer(dets, reasons)
            if stored:
                for c in (0, 1):
                    if reasons[c] is None:
                        self.footprints[c].extend(view_hulls([feature_points(dets[c])]))
            lines, oks = [], []
            for c in (0, 1):
                usable = reasons[c] is None
                oks.append(usable)
                if stored:
                    lines.append(why if usable else f"not used: {reasons[c]}")
                else:
                    lines.append(f"ok; not stored: {why}" if usable else str(reasons[c]))
            overlay = (([*self.footprints[0]], [*self.footprints[1]]), col.coverage(), col.min_views) \
                if drawing else None
            return PairOutcome(stored=stored, why=why, camera_lines=(lines[0], lines[1]), camera_ok=(oks[0], oks[1]),
                               shots=len(col.shots), both=col.both, ready=col.ready,
                               overlay=overlay)

    def restore(self, dets: tuple[Detection, Detection]) -> None:
        """Store a shot of a resumed session (:meth:`StereoCollector.restore`)."""
        with self.lock:
            used = self.collector.restore(dets)
            for c in (0, 1):
                if used[c]:
                    self.footprints[c].extend(view_hulls([feature_points(dets[c])]))

    def picture(self, images: tuple[np.ndarray, np.ndarray], dets: tuple[Detection, Detection],
                outcome: PairOutcome) -> np.ndarray | None:
        """The ``~/detections`` picture: both cameras' frames side by side, each with its detection,
        its line, the footprints of its stored views and its coverage panel (None when nobody
        watches)."""
        if outcome.overlay is None:
            return None
        footprints, coverage, min_views = outcome.overlay
        halves = [draw_live_overlay(images[c], dets[c], footprints[c], coverage[c], outcome.both, min_views,
                                    outcome.ready, f"{SIDES[c]}: {outcome.camera_lines[c]}",
                                    verdict_ok=outcome.camera_ok[c]) for c in (0, 1)]
        h = max(p.shape[0] for p in halves)
        halves = [np.pad(p, ((0, h - p.shape[0]), (0, 0), (0, 0))) for p in halves]
        return np.hstack(halves)

    def snapshot(self) -> StereoSnapshot:
        with self.lock:
            col = self.collector
            return StereoSnapshot(list(col.shots), col.min_views, col.both,
                                  (len(col.cameras[0].views), len(col.cameras[1].views)), dict(col.rejected),
                                  (dict(col.cameras[0].rejected), dict(col.cameras[1].rejected)))

    def clear(self) -> int:
        """Forget the stored shots; returns how many there were."""
        with self.lock:
            for f in self.footprints:
                f.clear()
            return self.collector.clear()

    def set_limits(self, min_views: int | None = None, max_views: int | None = None,
                   min_distance: float | None = None, max_motion_px: float | None = None) -> None:
        with self.lock:
            self.collector.set_limits(min_views, max_views, min_distance)
            if max_motion_px is not None:
                for g in self.gates:
                    g.max_motion_px = float(max_motion_px)

    def refusal(self, snap: StereoSnapshot, notes: list[str]) -> str:
        """Why ``snap`` cannot be calibrated yet and what to do: ``notes`` (frames that never pair,
        frames dropped while the detector was busy) first, then moving frames, else how to collect."""
        head = (f"{snap.both} shot(s) seen by both cameras; need {snap.min_views} (left {snap.views[0]} view(s), "
                f"right {snap.views[1]})")
        rejections = f"rejections: {snap.rejected or 'none'}; left: {snap.camera_rejected[0] or 'none'}; right: " \
                     f"{snap.camera_rejected[1] or 'none'}"
        causes = [n for n in notes if n]
        moving = [sum(v for k, v in r.items() if k == MOVING) for r in snap.camera_rejected]
        if max(moving) and max(moving) >= max(sum(r.values()) for r in snap.camera_rejected) / 2:
            causes.append(f"{max(moving)} frame(s) were moving (features moved max_motion_px "
                          f"{self.gates[0].max_motion_px:g} px or more between frames): hold the target still")
        if causes:
            return f"{head}. {'. '.join(causes)} ({rejections})"
        return f"{head}. Move the target through the field both cameras see ({rejections})"
