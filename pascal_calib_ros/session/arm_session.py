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
  newest sample: the arm rests and its driver has not published again yet), else refused with
  the reason (how far the samples are from the frame, and why poses were set aside);
* **stamps that cannot be right do not poison the buffer**: a pose stamped more than
  :data:`STAMP_TOLERANCE_S` ahead of the frame being examined (plus the time since it arrived) or
  behind it is set aside, counted, with the reason ("robot poses stamped 3600 s after the frame:
  clock step or wrong stamps"); a pose stamped more than :data:`JUMP_BACK_S` before the newest
  sample (a clock step back, a restarted driver, a looped bag) starts the buffer over, and says so;
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

from ..detect import Detection
from ..geometry import Transform, ellipses_from_conics, interpolate
from .answer import Answer
from .rejection import Rejection, RejectionKind

ROBOT_STILL_MM = 0.1  # the robot moved if its pose changed by more than this between two frames
ROBOT_STILL_DEG = 0.01
POSE_HORIZON_S = 30.0  # robot pose samples kept (older ones are dropped)
JUMP_BACK_S = 2.0  # a pose stamped this much before the newest sample: the clock went back, start over
STAMP_TOLERANCE_S = 10.0  # a pose stamped this much ahead of (or behind) the examined frames is set aside
MAX_ASIDE = 200  # poses set aside that are kept, in case the frames' clock follows theirs
NOTE_FRESH_S = 30.0  # a refusal quotes why poses were set aside (or the buffer started over) this long after
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
    """Robot pose samples (T_base_tool) by stamp (ns); thread-safe; bounded in time and count. Poses
    whose stamps cannot belong to the frames are set aside, and a jump back starts it over (module
    docstring); ``jump_back_s=None``: no restart (a recorded bag read whole, in any order)."""

    def __init__(self, horizon_s: float = POSE_HORIZON_S, max_samples: int = MAX_POSE_SAMPLES,
                 jump_back_s: float | None = JUMP_BACK_S, tolerance_s: float = STAMP_TOLERANCE_S) -> None:
        self.horizon_ns = int(horizon_s * 1e9)
        self.max_samples = max_samples
        self.jump_back_ns = None if jump_back_s is None else int(jump_back_s * 1e9)
        self.tolerance_ns = int(tolerance_s * 1e9)
        self._stamps: list[int] = []
        self._poses: list[Transform] = []
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self._frame: tuple[int, float] | None = None  # (stamp ns, monotonic s) of the newest examined frame
        self._aside: list[tuple[int, Transform]] = []  # the newest poses set aside (note_frame may take them back)
        self.received = 0
        self.set_aside = 0  # poses refused for their stamp since the last clear()
        self.restarts = 0  # backward jumps since the last clear()
        self.stamp_note = ""  # the last pose set aside, or the last restart: why
        self._note_at = 0.0  # monotonic s of stamp_note

    def __len__(self) -> int:
        return len(self._stamps)

    def note_frame(self, stamp_ns: int, now: float | None = None) -> None:
        """A frame with this stamp is being examined: pose stamps are judged against it. Poses set
        aside whose stamps fit this frame (the frames' clock followed the poses' step) are taken
        back."""
        with self._lock:
            self._frame = (stamp_ns, time.monotonic() if now is None else now)
            if self._aside and abs(self._aside[-1][0] - stamp_ns) <= self.tolerance_ns:
                aside, self._aside = self._aside, []
                for t, pose in aside:
                    if not self._misplaced(t, now):
                        self._keep(t, pose, now)

    def _misplaced(self, stamp_ns: int, now: float | None) -> str:
        """Why a pose stamped ``stamp_ns`` cannot belong to the frames being examined (empty: it can)."""
        if self._frame is None:
            return ""
        frame_ns, seen = self._frame
        elapsed_ns = int(max((time.monotonic() if now is None else now) - seen, 0.0) * 1e9)
        if stamp_ns > frame_ns + elapsed_ns + self.tolerance_ns:
            return (f"robot poses stamped {(stamp_ns - frame_ns) * 1e-9:.0f} s after the frame: clock step or "
                    "wrong stamps (set aside)")
        if stamp_ns < frame_ns - self.tolerance_ns:
            return (f"robot poses stamped {(frame_ns - stamp_ns) * 1e-9:.0f} s before the frame: clock step or "
                    "wrong stamps (set aside)")
        return ""

    def add(self, stamp_ns: int, pose: Transform, now: float | None = None) -> bool:
        """Keep a sample (False: set aside for its stamp, :attr:`stamp_note` says why)."""
        with self._lock:
            self.received += 1
            why = self._misplaced(stamp_ns, now)
            if why:
                self.set_aside += 1
                self._note(why, now)
                self._aside.append((stamp_ns, pose))
                del self._aside[:-MAX_ASIDE]
                return False
            self._keep(stamp_ns, pose, now)
            return True

    def _keep(self, stamp_ns: int, pose: Transform, now: float | None) -> None:
        """Insert a sample (the lock held): start over on a jump back, drop what is out of bounds."""
        if self.jump_back_ns is not None and self._stamps and stamp_ns < self._stamps[-1] - self.jump_back_ns:
            self.restarts += 1
            self._note(f"robot pose stamps jumped back {(self._stamps[-1] - stamp_ns) * 1e-9:.1f} s (clock step "
                       "back, driver restart or looped bag): pose buffer started over", now)
            self._stamps.clear()
            self._poses.clear()
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

    def _note(self, why: str, now: float | None) -> None:
        self.stamp_note, self._note_at = why, time.monotonic() if now is None else now

    def wait_until_covers(self, stamp_ns: int, timeout_s: float) -> bool:
        """Note the frame (:meth:`note_frame`), then wait (at most ``timeout_s``) until a sample at
        or after ``stamp_ns`` has arrived: an image and the pose published for it come on
        different topics, and the image may be examined first (tf2's message filter waits the same
        way). True if one has arrived."""
        self.note_frame(stamp_ns)
        with self._arrived:
            return self._arrived.wait_for(lambda: bool(self._stamps) and self._stamps[-1] >= stamp_ns,
                                          timeout=max(timeout_s, 0.0))

    def clear(self) -> None:
        """Forget every sample, the frame reference and the stamp notes (``~/reset``)."""
        with self._lock:
            self._stamps.clear()
            self._poses.clear()
            self._frame = None
            self._aside.clear()
            self.set_aside = self.restarts = 0
            self.stamp_note = ""

    def describe(self) -> str:
        """The buffer in a line for ``~/status``: samples held and their span, poses set aside, restarts."""
        with self._lock:
            n = len(self._stamps)
            span = (self._stamps[-1] - self._stamps[0]) * 1e-9 if n else 0.0
            out = f"{n} sample(s) over {span:.2f} s"
            if self.set_aside:
                out += f"; {self.set_aside} set aside for their stamps"
            if self.restarts:
                out += f"; started over {self.restarts} time(s) on a backward jump"
            return out + (f"; last: {self.stamp_note}" if self.stamp_note else "")

    def lookup(self, stamp_ns: int, max_age_s: float, now: float | None = None) -> tuple[Transform | None, str]:
        """The pose at ``stamp_ns`` (module docstring) or (None, the reason; with why poses were
        set aside or the buffer started over, if that happened in the last :data:`NOTE_FRESH_S`)."""
        max_age = int(max_age_s * 1e9)
        with self._lock:
            fresh = (time.monotonic() if now is None else now) - self._note_at <= NOTE_FRESH_S
            note = f"; {self.stamp_note}" if self.stamp_note and fresh else ""
            if not self._stamps:
                kept = f"none kept of {self.received} received" if self.received else "none received yet"
                return None, f"{NO_POSE} ({kept}{note})"
            k = bisect.bisect_left(self._stamps, stamp_ns)
            if k < len(self._stamps) and self._stamps[k] == stamp_ns:
                return self._poses[k], ""
            before = (self._stamps[k - 1], self._poses[k - 1]) if k > 0 else None
            after = (self._stamps[k], self._poses[k]) if k < len(self._stamps) else None
        if before and after and stamp_ns - before[0] <= max_age and after[0] - stamp_ns <= max_age:
            s = (stamp_ns - before[0]) / (after[0] - before[0])
            return interpolate(before[1], after[1], s), ""
        near = [(abs(stamp_ns - x[0]), x[0], x[1]) for x in (before, after) if x is not None]
        gap, at, pose = min(near, key=lambda x: x[0])
        if gap <= max_age:
            return pose, ""
        if gap > self.tolerance_ns and not note:
            note = (f"; robot poses stamped {gap * 1e-9:.0f} s after the frame: clock step or wrong stamps"
                    if at > stamp_ns else f"; the newest robot pose is stamped {gap * 1e-9:.0f} s before the frame: "
                    "the poses stopped arriving, or a clock step or wrong stamps")
        return None, (f"{NO_POSE} (nearest sample {gap * 1e-9:.3f} s from the image stamp; "
                      f"pose_max_age {max_age_s:g} s{note})")

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
    rejection: Rejection | None = None  # why not (the detection's reason, "moving (...)", "no robot pose (...)")
    robot_pose: Transform | None = None
    robot_still: bool | None = None  # None: unknown (no robot poses or no pose at a stamp)

    @property
    def reason(self) -> str:
        """The refusal's message ("" when usable)."""
        return "" if self.rejection is None else self.rejection.message

    @property
    def why(self) -> Rejection:
        """The refusal of a frame that is not usable."""
        if self.rejection is None:
            raise ValueError("a usable frame has no rejection")
        return self.rejection

    @property
    def moving(self) -> bool:
        return self.rejection is not None and self.rejection.kind is RejectionKind.MOVING


@dataclass
class StillnessGate:
    """Compares each examined frame with the previous one (module docstring)."""

    max_motion_px: float = 0.5  # 0: no stillness check
    robot_still_mm: float = ROBOT_STILL_MM
    robot_still_deg: float = ROBOT_STILL_DEG
    prev: Detection | None = None
    prev_stamp_ns: int | None = None

    def _target_motion(self, prev: Detection | None, det: Detection) -> str:
        """Why the target counts as moving since ``prev`` ("" if it stood still)."""
        if prev is None:
            return f"{MOVING} (first frame: nothing to compare with)"
        motion = feature_motion_px(prev, det) if prev.ok else None
        if motion is None:
            return f"{MOVING} (the previous frame had no matching target features)"
        if motion >= self.max_motion_px:
            return f"{MOVING} (target moved {motion:.2f} px between frames; max_motion_px {self.max_motion_px:g})"
        return ""

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
            return Verdict(False, Rejection(RejectionKind.TARGET, det.reason), robot_still=robot_still)
        if self.max_motion_px > 0:
            moving = self._target_motion(prev, det) if not robot_note else robot_note
            if moving:
                return Verdict(False, Rejection(RejectionKind.MOVING, moving), robot_still=robot_still)
        pose: Transform | None = None
        if poses is not None:
            pose, why = poses.lookup(stamp_ns, max_age_s)
            if pose is None:
                return Verdict(False, Rejection(RejectionKind.NO_POSE, why), robot_still=robot_still)
        return Verdict(True, None, pose, robot_still)


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
    if verdict.rejection is not None and verdict.rejection.kind is RejectionKind.NO_POSE:
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

    def wait(self, capture: Capture, timeout_s: float, now: float | None = None) -> Answer:
        """Block until the request is answered or its deadline passes (then refuse it)."""
        left = capture.deadline - (time.monotonic() if now is None else now)
        capture.done.wait(max(0.0, left))
        if not capture.done.is_set():
            if capture.frames:
                why = f"no still frame among {capture.frames} examined; last: {capture.last_reason}"
            else:
                why = "no frame arrived"
            self.finish(capture, False, f"nothing stored within {timeout_s:g} s (capture_timeout): {why}")
        return Answer(capture.success, capture.message)


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
