"""A live calibration session, ROS-free and thread-safe: what the node does with each examined frame.

Every examined frame goes through the stillness gate (:class:`~.arm_session.StillnessGate`: the
target, and the robot with poses, must stand still); a frame that a ``~/capture`` waits for is
stored whatever it resembles (:class:`~.arm_session.CaptureSlot`); otherwise, with
``collect="auto"``, a usable frame is stored when it adds diversity (:class:`~.collector.
ViewCollector`). The session keeps the stored views' footprints for the live picture, and says why
a calibration cannot start yet (:meth:`LiveSession.refusal`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..detect import Detection, feature_points
from ..geometry import Transform, view_hulls
from .answer import Answer
from .arm_session import MOVING, CaptureSlot, PoseBuffer, StillnessGate, capture_is_final, stored_message
from .collector import ViewCollector
from .overlay import draw_live_overlay
from .rejection import Rejection, RejectionKind

Persist = Callable[[Detection, "Transform | None"], str]  # writes a stored view; says what it did
NOT_WRITTEN = "not written"  # how a failed ``persist`` answer starts

MOTION_AUTO_PX = 0.5  # the stillness threshold of robot sessions when max_motion_px is -1 (auto)
GUIDED_MOTION_AUTO_PX = 2.0  # a guided hand-held session (auto): still enough for a person holding the target


def max_motion_of(value: float, collect: str, with_poses: bool, guided: bool = False) -> float:
    """The stillness threshold in force: ``value`` when >= 0; -1 (auto): :data:`MOTION_AUTO_PX` for
    robot sessions (robot poses, or ``collect="on_capture"``), :data:`GUIDED_MOTION_AUTO_PX` for a
    guided hand-held session, else off (0)."""
    if value >= 0:
        return float(value)
    if with_poses or collect == "on_capture":
        return MOTION_AUTO_PX
    return GUIDED_MOTION_AUTO_PX if guided else 0.0


@dataclass(frozen=True)
class Snapshot:
    """The stored views (and their robot poses) at one moment, for a calibration."""

    views: list[Detection]
    robot_poses: list[Transform | None]
    min_views: int
    rejected: dict[str, int]


@dataclass
class FrameOutcome:
    """What became of one examined frame: stored or not, the line shown on the live picture (and
    its colour), the answer to a waiting ``~/capture``, the view count and readiness."""

    accepted: bool
    why: str
    verdict_ok: bool
    capture_answer: Answer | None
    views: int
    ready: bool
    overlay: tuple[list[np.ndarray], dict[str, float], int] | None  # footprints, coverage, min views
    robot_pose: Transform | None = None  # the stored view's robot pose
    written: str = ""  # what became of the stored view on the disk (``persist``'s answer)


class LiveSession:
    """The collection state of a live session; every method may be called from any thread."""

    def __init__(self, min_views: int, max_views: int, min_distance: float, max_motion_px: float,
                 collect: str, board_points: np.ndarray | None = None) -> None:
        """``board_points``: the target's board corners on the sheet, to place a view of a target
        without circles (:func:`.collector.view_parameters`)."""
        self.lock = threading.Lock()
        self.collector = ViewCollector(min_views, max_views, min_distance, board_points=board_points)
        self.footprints: list[np.ndarray] = []  # convex hulls of the stored views' features
        self.gate = StillnessGate(max_motion_px)
        self.captures = CaptureSlot()
        self.collect = collect

    def bad_frame(self, reason: str) -> None:
        """Count a frame that could not be converted."""
        with self.lock:
            self.collector.reject(Rejection(RejectionKind.BAD_FRAME, f"bad frame: {reason}"))

    def examine(self, det: Detection, stamp_ns: int, poses: PoseBuffer | None, pose_max_age: float,
                received_at: float, drawing: bool, guide: Answer | None = None,
                persist: Persist | None = None) -> FrameOutcome:
        """Apply the session's policy to one frame's detection (module docstring); ``drawing``: also
        return what the live picture needs; ``persist``: writes a stored view (its detection and robot
        pose) before a waiting ``~/capture`` is answered, and says what it did (an error is appended to
        the answer: the view stays in memory). ``guide`` (a guided session, :mod:`.guided_live`): with
        ``collect="auto"`` a usable, still frame is stored only when ``guide.ok`` (it matches the
        suggestion; then whatever it resembles), else its line says ``guide.message``."""
        verdict = self.gate.examine(det, stamp_ns, poses, pose_max_age)
        capture = self.captures.for_frame(received_at)
        answer: Answer | None = None
        accepted = False
        why = verdict.reason or ("ok" if det.ok else det.reason)
        with self.lock:
            col = self.collector
            if capture is not None:
                if capture_is_final(verdict, poses is not None):
                    if verdict.usable:
                        accepted, why = col.offer(det, verdict.robot_pose, force=True)
                    else:
                        accepted, why = col.reject(verdict.why)
                    answer = Answer(accepted, stored_message(len(col.views) - 1, det, verdict.robot_pose)
                                    if accepted else f"nothing stored: {why}")
                    why = answer.message
                else:
                    col.reject(verdict.why)
                    self.captures.note(capture, verdict.reason)
            elif self.collect == "auto" and guide is not None:
                if verdict.usable and guide.ok:
                    accepted, why = col.offer(det, verdict.robot_pose, force=True)
                    why = f"view {len(col.views) - 1} stored" if accepted else f"ok; not stored: {why}"
                elif verdict.usable:
                    why = f"ok; not stored: {guide.message}"
                else:
                    col.reject(verdict.why)
            elif self.collect == "auto":
                if verdict.usable:
                    accepted, why = col.offer(det, verdict.robot_pose)
                    why = f"view {len(col.views) - 1} stored" if accepted else f"ok; not stored: {why}"
                else:
                    col.reject(verdict.why)
            elif verdict.usable:
                why = "ok; ~/capture stores a view (collect:=on_capture)"
            if accepted:  # only stored views cost a hull
                self.footprints.extend(view_hulls([feature_points(det)]))
            overlay = (list(self.footprints), col.coverage(), col.min_views) if drawing else None
            n, ready = len(col.views), col.ready
        written = persist(det, verdict.robot_pose) if accepted and persist is not None else ""
        if answer is not None and written.startswith(NOT_WRITTEN):
            answer = Answer(answer.ok, f"{answer.message}; {written}")
        if capture is not None and answer is not None:
            self.captures.finish(capture, *answer)
        return FrameOutcome(accepted=accepted, why=why, verdict_ok=verdict.usable and (accepted or capture is None),
                            capture_answer=answer, views=n, ready=ready, overlay=overlay,
                            robot_pose=verdict.robot_pose if accepted else None, written=written)

    def restore(self, det: Detection, robot_pose: Transform | None) -> None:
        """Store a view of a resumed session (already chosen once: whatever it resembles)."""
        with self.lock:
            accepted, _ = self.collector.offer(det, robot_pose, force=True)
            if accepted:
                self.footprints.extend(view_hulls([feature_points(det)]))

    def picture(self, img: np.ndarray, det: Detection, outcome: FrameOutcome) -> np.ndarray | None:
        """The ``~/detections`` picture of a frame (None when nobody watches)."""
        if outcome.overlay is None:
            return None
        footprints, coverage, min_views = outcome.overlay
        return draw_live_overlay(img, det, footprints, coverage, outcome.views, min_views, outcome.ready,
                                 outcome.why, verdict_ok=outcome.verdict_ok)

    def snapshot(self) -> Snapshot:
        with self.lock:
            col = self.collector
            return Snapshot(list(col.views), list(col.robot_poses), col.min_views, dict(col.rejected))

    def clear(self) -> int:
        """Forget the stored views; returns how many there were."""
        with self.lock:
            self.footprints.clear()
            return self.collector.clear()

    def refusal(self, snap: Snapshot, dropped: int, dropped_note: str) -> str:
        """Why ``snap`` cannot be calibrated yet and what to do: every cause that applies, the most
        frequent first (frames dropped unexamined, moving frames), else how to collect views."""
        rejected = snap.rejected
        n, need = len(snap.views), snap.min_views
        rejections = f"rejections: {rejected or 'none'}"
        moving = rejected.get(MOVING, 0)
        causes = []
        if moving and moving >= sum(rejected.values()) / 2:
            causes.append(f"{moving} frame(s) were moving (features moved max_motion_px {self.gate.max_motion_px:g} "
                          "px or more between frames, or the robot moved): hold the target and the arm still at each "
                          "pose")
        if dropped_note:
            causes.insert(0 if dropped > moving else len(causes), dropped_note)
        if causes:
            return f"{n} view(s) collected; need {need}. {'. '.join(causes)} ({rejections})"
        if self.collect == "on_capture":
            return (f"{n} view(s) collected; need {need}. Call ~/capture at each pose (collect:=on_capture; "
                    f"{rejections})")
        return f"{n} view(s) collected; need {need}. Move the target through the image ({rejections})"

    def set_limits(self, min_views: int | None = None, max_views: int | None = None,
                   min_distance: float | None = None, max_motion_px: float | None = None) -> None:
        """Change the collector's limits and the stillness threshold at run time."""
        with self.lock:
            col = self.collector
            col.min_views = col.min_views if min_views is None else int(min_views)
            col.max_views = col.max_views if max_views is None else int(max_views)
            col.min_distance = col.min_distance if min_distance is None else float(min_distance)
            if max_motion_px is not None:
                self.gate.max_motion_px = float(max_motion_px)
