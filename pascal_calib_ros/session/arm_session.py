"""Robot-arm sessions, the ROS-free part: still frames, robot poses by image stamp, ``~/capture``.

An arm carries the camera (eye in hand) or the target (eye to hand) through poses and stops at
each; a script calls the calibration node's ``~/capture`` service. This module decides, for every
examined frame:

* **stillness**: the target's image features (every detected circle's ellipse: centre and both
  semi-axes, and the checkerboard corners) moved less than ``max_motion_px`` since the previous
  examined frame, and, with robot poses, the robot did not move between the two frames' stamps
  (every pose sample between them and the poses at both stamps within
  :data:`ROBOT_STILL_MM` / :data:`ROBOT_STILL_DEG` of the pose at the newer stamp). A frame
  without a detected target in it or in the previous frame cannot show that the target stood
  still and counts as moving unless it is rejected for its own reason first;
* **the robot pose at the image stamp** (:class:`PoseBuffer`): interpolated between the two
  nearest samples around the stamp (slerp of the rotation, linear translation) when both lie
  within ``max_age`` of it, else the nearest sample within ``max_age`` (a stamp just after the
  newest sample: the arm rests and its driver has not published again yet), else refused;
* **captures** (:class:`CaptureSlot`): one request at a time; the first frame *received after*
  the request that is still decides it: stored, or refused with the reason (no target, cut by the
  border, blurred, no robot pose). Frames that are moving are skipped until ``capture_timeout``,
  after which the request is refused with the last reason.
"""

from __future__ import annotations

import bisect
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from ..detect.detection import Detection
from ..geometry.conic import ellipses_from_conics
from ..geometry.transform import Transform, interpolate

ROBOT_STILL_MM = 0.1  # the robot moved if its pose changed by more than this between two frames
ROBOT_STILL_DEG = 0.01
POSE_HORIZON_S = 30.0  # robot pose samples kept (older ones are dropped)
MAX_POSE_SAMPLES = 20000
MOVING = "moving"
NO_POSE = "no robot pose"


# -- stillness ----------------------------------------------------------------------------------

def _features(det: Detection) -> dict[tuple[str, int], np.ndarray]:
    """Comparable features of a detection: per circle (cx, cy, a, b), per corner (x, y)."""
    out: dict[tuple[str, int], np.ndarray] = {}
    if det.edges:
        par, real = ellipses_from_conics(np.array([e.conic for e in det.edges]))
        for e, p, ok in zip(det.edges, par, real, strict=True):
            if ok:
                out[("circle", e.circle)] = np.array([p[0], p[1], max(p[2], p[3]), min(p[2], p[3])])
    if det.corners is not None:
        for k, c in enumerate(np.asarray(det.corners, float).reshape(-1, 2)):
            out[("corner", k)] = c
    return out


def feature_motion_px(prev: Detection, cur: Detection) -> float | None:
    """Largest change of any feature present in both detections (centre shift, semi-axis
    change, corner shift) in px; None if the two have no feature in common."""
    a, b = _features(prev), _features(cur)
    common = [k for k in b if k in a]
    if not common:
        return None
    worst = 0.0
    for k in common:
        d = b[k] - a[k]
        shift = float(np.hypot(d[0], d[1]))
        worst = max(worst, shift, *(abs(float(v)) for v in d[2:]))
    return worst


def pose_change(a: Transform, b: Transform) -> tuple[float, float]:
    """(translation mm, rotation deg) between two poses."""
    d = a.inverse() @ b
    return 1000.0 * float(np.linalg.norm(a.translation - b.translation)), d.angle_deg()


# -- robot poses by stamp -----------------------------------------------------------------------

class PoseBuffer:
    """Robot pose samples (T_base_tool) by stamp (ns); thread-safe; bounded in time and count."""

    def __init__(self, horizon_s: float = POSE_HORIZON_S, max_samples: int = MAX_POSE_SAMPLES) -> None:
        self.horizon_ns = int(horizon_s * 1e9)
        self.max_samples = max_samples
        self._stamps: list[int] = []
        self._poses: list[Transform] = []
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self.received = 0

    def __len__(self) -> int:
        return len(self._stamps)

    def add(self, stamp_ns: int, pose: Transform) -> None:
        with self._lock:
            self.received += 1
            k = bisect.bisect_right(self._stamps, stamp_ns)
            if k > 0 and self._stamps[k - 1] == stamp_ns:  # a repeated stamp: the newer message wins
                self._poses[k - 1] = pose
                return
            self._stamps.insert(k, stamp_ns)
            self._poses.insert(k, pose)
            cut = bisect.bisect_left(self._stamps, self._stamps[-1] - self.horizon_ns)
            cut = max(cut, len(self._stamps) - self.max_samples)
            if cut > 0:
                del self._stamps[:cut], self._poses[:cut]
            self._arrived.notify_all()

    def wait_until_covers(self, stamp_ns: int, timeout_s: float) -> bool:
        """Wait (at most ``timeout_s``) until a sample at or after ``stamp_ns`` has arrived: an
        image and the pose published for it come on different topics, and the image may be
        examined first (tf2's message filter waits the same way). True if one has arrived."""
        with self._arrived:
            return self._arrived.wait_for(lambda: bool(self._stamps) and self._stamps[-1] >= stamp_ns,
                                          timeout=max(timeout_s, 0.0))

    def clear(self) -> None:
        with self._lock:
            self._stamps.clear()
            self._poses.clear()

    def lookup(self, stamp_ns: int, max_age_s: float) -> tuple[Transform | None, str]:
        """The pose at ``stamp_ns`` (module docstring) or (None, the reason)."""
        max_age = int(max_age_s * 1e9)
        with self._lock:
            if not self._stamps:
                return None, f"{NO_POSE} (none received yet)"
            k = bisect.bisect_left(self._stamps, stamp_ns)
            if k < len(self._stamps) and self._stamps[k] == stamp_ns:
                return self._poses[k], ""
            before = (self._stamps[k - 1], self._poses[k - 1]) if k > 0 else None
            after = (self._stamps[k], self._poses[k]) if k < len(self._stamps) else None
        if before and after and stamp_ns - before[0] <= max_age and after[0] - stamp_ns <= max_age:
            s = (stamp_ns - before[0]) / (after[0] - before[0])
            return interpolate(before[1], after[1], s), ""
        near = [(abs(stamp_ns - x[0]), x[1]) for x in (before, after) if x is not None]
        gap, pose = min(near, key=lambda x: x[0])
        if gap <= max_age:
            return pose, ""
        return None, (f"{NO_POSE} (nearest sample {gap * 1e-9:.3f} s from the image stamp; "
                      f"pose_max_age {max_age_s:g} s)")

    def motion_between(self, t0_ns: int, t1_ns: int, max_age_s: float) -> tuple[float, float] | None:
        """Largest change (mm, deg) of the robot pose over [t0, t1] relative to the pose at t1
        (the samples between and the poses at both ends); None if a pose at an end is unknown."""
        p0, _ = self.lookup(t0_ns, max_age_s)
        p1, _ = self.lookup(t1_ns, max_age_s)
        if p0 is None or p1 is None:
            return None
        lo, hi = min(t0_ns, t1_ns), max(t0_ns, t1_ns)
        with self._lock:
            i, j = bisect.bisect_left(self._stamps, lo), bisect.bisect_right(self._stamps, hi)
            between = self._poses[i:j]
        mm, deg = 0.0, 0.0
        for p in [p0, *between]:
            a, b = pose_change(p, p1)
            mm, deg = max(mm, a), max(deg, b)
        return mm, deg


# -- one frame's verdict ------------------------------------------------------------------------

@dataclass
class Verdict:
    """What an examined frame may be used for."""

    usable: bool  # detected, still, and (with robot poses) a pose at its stamp: may be stored
    reason: str = ""  # why not (the detection's reason, "moving (...)", "no robot pose (...)")
    robot_pose: Transform | None = None
    robot_still: bool | None = None  # None: unknown (no robot poses or no pose at a stamp)

    @property
    def moving(self) -> bool:
        return self.reason.startswith(MOVING)


@dataclass
class StillnessGate:
    """Compares each examined frame with the previous one (module docstring)."""

    max_motion_px: float = 0.5  # 0: no stillness check
    robot_still_mm: float = ROBOT_STILL_MM
    robot_still_deg: float = ROBOT_STILL_DEG
    prev: Detection | None = None
    prev_stamp_ns: int | None = None

    def examine(self, det: Detection, stamp_ns: int, poses: PoseBuffer | None, max_age_s: float) -> Verdict:
        prev, prev_stamp = self.prev, self.prev_stamp_ns
        self.prev, self.prev_stamp_ns = det, stamp_ns
        robot_still: bool | None = None
        robot_note = ""
        if poses is not None and prev_stamp is not None and self.max_motion_px > 0:
            moved = poses.motion_between(prev_stamp, stamp_ns, max_age_s)
            if moved is not None:
                robot_still = moved[0] <= self.robot_still_mm and moved[1] <= self.robot_still_deg
                if not robot_still:
                    robot_note = f"{MOVING} (robot moved {moved[0]:.2f} mm, {moved[1]:.3f} deg between frames)"
        if not det.ok:
            return Verdict(False, det.reason, robot_still=robot_still)
        if self.max_motion_px > 0:
            if robot_note:
                return Verdict(False, robot_note, robot_still=robot_still)
            if prev is None:
                return Verdict(False, f"{MOVING} (first frame: nothing to compare with)", robot_still=robot_still)
            motion = feature_motion_px(prev, det) if prev.ok else None
            if motion is None:
                return Verdict(False, f"{MOVING} (the previous frame had no matching target features)",
                               robot_still=robot_still)
            if motion >= self.max_motion_px:
                return Verdict(False, f"{MOVING} (target moved {motion:.2f} px between frames; max_motion_px "
                                      f"{self.max_motion_px:g})", robot_still=robot_still)
        pose: Transform | None = None
        if poses is not None:
            pose, why = poses.lookup(stamp_ns, max_age_s)
            if pose is None:
                return Verdict(False, why, robot_still=robot_still)
        return Verdict(True, "", pose, robot_still)


# -- captures -----------------------------------------------------------------------------------

@dataclass
class Capture:
    requested_at: float  # monotonic seconds; only frames received afterwards count
    deadline: float
    done: threading.Event = field(default_factory=threading.Event)
    success: bool = False
    message: str = ""
    frames: int = 0  # frames examined for it
    last_reason: str = ""


def capture_is_final(verdict: Verdict, with_poses: bool) -> bool:
    """Whether a frame decides a capture: a usable frame, or a refusal for a reason other than
    motion (a failed detection decides only if the robot is known to stand still or there are
    no robot poses to tell)."""
    if verdict.usable:
        return True
    if verdict.moving:
        return False
    if verdict.reason.startswith(NO_POSE):
        return True
    return not with_poses or verdict.robot_still is True


class CaptureSlot:
    """One pending ``~/capture`` at a time; the detector thread answers it, the service waits."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.pending: Capture | None = None
        self.stored = 0
        self.refused = 0

    def open(self, timeout_s: float, now: float | None = None) -> Capture | None:
        """A new request, or None if one is pending."""
        now = time.monotonic() if now is None else now
        with self._lock:
            if self.pending is not None:
                return None
            self.pending = Capture(now, now + timeout_s)
            return self.pending

    def for_frame(self, received_at: float) -> Capture | None:
        """The pending request a frame received at ``received_at`` may answer."""
        with self._lock:
            c = self.pending
            return c if c is not None and received_at >= c.requested_at and not c.done.is_set() else None

    def finish(self, capture: Capture, success: bool, message: str) -> bool:
        """Answer ``capture`` (False if it was already answered or timed out)."""
        with self._lock:
            if capture.done.is_set():
                return False
            capture.success, capture.message = success, message
            capture.done.set()
            if self.pending is capture:
                self.pending = None
            if success:
                self.stored += 1
            else:
                self.refused += 1
            return True

    def note(self, capture: Capture, reason: str) -> None:
        with self._lock:
            capture.frames += 1
            capture.last_reason = reason

    def wait(self, capture: Capture, timeout_s: float, now: float | None = None) -> tuple[bool, str]:
        """Block until the request is answered or its deadline passes (then refuse it)."""
        left = capture.deadline - (time.monotonic() if now is None else now)
        capture.done.wait(max(0.0, left))
        if not capture.done.is_set():
            if capture.frames:
                why = f"no still frame among {capture.frames} examined; last: {capture.last_reason}"
            else:
                why = "no frame arrived"
            self.finish(capture, False, f"nothing stored within {timeout_s:g} s (capture_timeout): {why}")
        return capture.success, capture.message


def view_placement(det: Detection) -> tuple[float, float, float, float] | None:
    """(x px, y px, tilt deg, size px) of a detection's target: the mean of its circle centres
    (or corners), the tilt from the axis ratio of its outer circle (median over a grid's
    circles), the size as sqrt(a b) of the outer circle."""
    f = _features(det)
    circles = np.array([v for k, v in f.items() if k[0] == "circle"])
    if len(circles):
        use = circles if len(circles) > 3 else circles[:1]
        ratio = float(np.median(use[:, 3] / use[:, 2]))
        return (float(use[:, 0].mean()), float(use[:, 1].mean()),
                float(np.degrees(np.arccos(np.clip(ratio, 0.0, 1.0)))), float(np.sqrt(use[0, 2] * use[0, 3])))
    corners = np.array([v for k, v in f.items() if k[0] == "corner"])
    if len(corners):
        return float(corners[:, 0].mean()), float(corners[:, 1].mean()), float("nan"), float("nan")
    return None


def stored_message(index: int, det: Detection, pose: Transform | None) -> str:
    """``view N stored: target at (x, y) px, tilt T deg[, robot tool at [...] m]``."""
    place = view_placement(det)
    msg = f"view {index} stored"
    if place is not None:
        x, y, tilt, _ = place
        msg += f": target at ({x:.1f}, {y:.1f}) px"
        if np.isfinite(tilt):
            msg += f", tilt {tilt:.1f} deg"
    if pose is not None:
        msg += ", robot tool at [" + ", ".join(f"{v:.4f}" for v in pose.translation) + "] m"
    return msg
