"""Robot-arm sessions without ROS: stillness of the target and of the robot, robot poses by
stamp (interpolation, maximum age), capture bookkeeping, what a capture answers."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.session.arm_session import (
    CaptureSlot,
    PoseBuffer,
    StillnessGate,
    Verdict,
    capture_is_final,
    feature_motion_px,
    stored_message,
    view_placement,
)
from pascal_calib_ros.session.collector import ViewCollector
from pascal_calib_ros.session.rejection import Rejection, RejectionKind
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import Target, resolve_target

S = 10**9


@pytest.fixture(scope="module")
def ring() -> Target:
    return resolve_target("ring_a4")


@pytest.fixture(scope="module")
def frames(ring: Target) -> dict[str, Detection]:
    """The ring at one pose rendered twice (sensor noise differs), shifted by 2 px, and an empty frame."""
    cam = SessionSpec(width=640, height=480).camera()
    R = np.array([[1, 0, 0], [0, np.cos(0.4), -np.sin(0.4)], [0, np.sin(0.4), np.cos(0.4)]])
    pose = Pose(R, np.array([0.0, 0.0, 0.9]))
    a = render_view(ring, cam, pose, SensorModel(seed=1)).image
    b = render_view(ring, cam, pose, SensorModel(seed=2)).image
    shifted = np.roll(a, 2, axis=1)
    empty = render_view(ring, cam, None, SensorModel(seed=3)).image
    dets = {k: detect_target(im, ring, name=k) for k, im in
            {"a": a, "b": b, "shifted": shifted, "empty": empty}.items()}
    assert dets["a"].ok and dets["b"].ok and dets["shifted"].ok and not dets["empty"].ok
    return dets


def test_feature_motion_of_still_and_moving_frames(frames: dict[str, Detection]) -> None:
    still = feature_motion_px(frames["a"], frames["b"])
    moved = feature_motion_px(frames["a"], frames["shifted"])
    assert still is not None and still < 0.1, still  # sensor noise only
    assert moved is not None and abs(moved - 2.0) < 0.1, moved
    assert feature_motion_px(frames["a"], frames["empty"]) is None
    x, y, tilt, size = view_placement(frames["a"])  # type: ignore[misc]
    assert 0 < x < 640 and 0 < y < 480 and 15 < tilt < 35 and size > 20  # tilted 23 deg, seen off-axis


def test_stillness_gate_never_passes_a_moving_target(frames: dict[str, Detection]) -> None:
    gate = StillnessGate(max_motion_px=0.5)
    first = gate.examine(frames["a"], 0, None, 0.1)
    assert not first.usable and first.moving and "first frame" in first.reason
    assert gate.examine(frames["b"], S // 10, None, 0.1).usable
    v = gate.examine(frames["shifted"], 2 * S // 10, None, 0.1)
    assert not v.usable and v.moving and "target moved 2.0" in v.reason, v
    # a frame after the empty one has nothing to compare with
    assert gate.examine(frames["empty"], 3 * S // 10, None, 0.1).reason == frames["empty"].reason
    after = gate.examine(frames["a"], 4 * S // 10, None, 0.1)
    assert after.moving and "previous frame" in after.reason
    # a target moving 2 px per frame: never usable, whatever the sequence
    gate = StillnessGate(max_motion_px=0.5)
    seq = [frames["a"], frames["shifted"]] * 4
    assert not any(gate.examine(d, k * S // 10, None, 0.1).usable for k, d in enumerate(seq))
    # 0 disables the check
    assert StillnessGate(max_motion_px=0.0).examine(frames["shifted"], 0, None, 0.1).usable


def test_pose_buffer_interpolates_and_refuses_old_poses() -> None:
    buf = PoseBuffer()
    ok, why = buf.lookup(5 * S, 0.1)
    assert ok is None and "none received yet" in why
    a = Transform.from_rotvec([0, 0, 0.0], [0.0, 0.0, 0.5])
    b = Transform.from_rotvec([0, 0, 0.2], [0.1, 0.0, 0.5])
    buf.add(10 * S, a)
    buf.add(10 * S + S // 20, b)  # 50 ms later
    exact = buf.lookup(10 * S, 0.1)[0]
    assert exact is a
    mid, _ = buf.lookup(10 * S + S // 40, 0.1)
    assert mid is not None
    np.testing.assert_allclose(mid.translation, [0.05, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(mid.rotvec, [0, 0, 0.1], atol=1e-12)
    # just after the newest sample: the arm rests, its driver has not published again
    late, _ = buf.lookup(10 * S + S // 20 + S // 50, 0.1)
    assert late is b
    # too far from any sample
    none, why = buf.lookup(11 * S, 0.1)
    assert none is None and "no robot pose" in why and "0.950 s" in why and "pose_max_age 0.1" in why
    none, why = buf.lookup(9 * S, 0.5)
    assert none is None and "1.000 s" in why
    # a gap larger than max_age around the stamp: the nearer side if it is within max_age
    buf.add(12 * S, b)
    near, _ = buf.lookup(12 * S - S // 20, 0.1)
    assert near is b
    # bounded in time
    small = PoseBuffer(horizon_s=1.0)
    for k in range(50):
        small.add(k * S // 10, a)
    assert len(small) <= 11 and small.received == 50


def test_pose_buffer_waits_for_the_pose_of_a_newer_image() -> None:
    """An image examined before the pose published for it (another topic, another callback)
    waits for it instead of being refused; without one it gives up after the timeout."""
    buf = PoseBuffer()
    a = Transform.from_rotvec([0, 0, 0.0], [0.0, 0.0, 0.5])
    buf.add(10 * S, a)
    assert buf.wait_until_covers(10 * S, 1.0)  # already there: no wait
    t0 = time.monotonic()
    assert not buf.wait_until_covers(11 * S, 0.05)
    assert time.monotonic() - t0 >= 0.04
    late = threading.Timer(0.05, buf.add, args=(11 * S, a))
    late.start()
    t0 = time.monotonic()
    assert buf.wait_until_covers(11 * S, 5.0)
    assert time.monotonic() - t0 < 4.0
    late.join()
    assert buf.lookup(11 * S, 0.1)[0] is a


def _frames_and_poses(buf: PoseBuffer, t0: float, n: int, pose: Transform, wall0: float = 1000.0) -> list:
    """``n`` frames at 10 Hz from ``t0`` s, each after the pose stamped with it (a driver resting at
    ``pose``), the wall clock advancing with the stamps; the lookups' results."""
    out = []
    for k in range(n):
        t = int(t0 * S) + k * S // 10
        buf.add(t, pose, now=wall0 + k * 0.1)
        buf.note_frame(t, now=wall0 + k * 0.1)
        out.append(buf.lookup(t, 0.1, now=wall0 + k * 0.1))
    return out


def test_a_pose_stamped_an_hour_ahead_is_set_aside_and_says_why() -> None:
    """Issue 34: one pose stamped an hour ahead used to keep only itself (the 30 s horizon from
    the newest stamp) and refuse every later frame. It is set aside now, with the reason."""
    buf = PoseBuffer()
    rest = Transform.from_rotvec([0.1, 0.2, 0.3], [0.4, 0.0, 0.5])
    assert all(p is not None for p, _ in _frames_and_poses(buf, 100.0, 5, rest))
    assert not buf.add(3700 * S, rest, now=1000.5)  # an hour ahead of the frames
    assert buf.set_aside == 1 and "stamped 3600 s after the frame: clock step or wrong stamps" in buf.stamp_note
    got = _frames_and_poses(buf, 100.5, 20, rest, wall0=1000.5)
    assert all(p is not None for p, _ in got), got  # every later frame has its pose
    # a frame far from every pose says why
    pose, why = buf.lookup(50 * S, 0.1, now=1003.0)
    assert pose is None and "robot poses stamped 3600 s after the frame" in why  # the fresh set-aside note
    assert "1 set aside for their stamps" in buf.describe()
    pose, why = buf.lookup(50 * S, 0.1, now=1100.0)  # later: the reason is the gap itself
    assert pose is None and "robot poses stamped 50 s after the frame: clock step or wrong stamps" in why, why
    # the frames' clock itself: poses behind the frames by more than the tolerance are set aside too
    assert not buf.add(60 * S, rest, now=1003.0)
    assert "stamped 42 s before the frame" in buf.stamp_note, buf.stamp_note
    # the whole clock steps forward: the poses ahead wait aside, taken back by the first frame they fit
    step = PoseBuffer()
    _frames_and_poses(step, 100.0, 3, rest)
    assert not step.add(3700 * S, rest, now=1000.3)
    step.note_frame(3700 * S + S // 20, now=1000.35)
    assert step.lookup(3700 * S + S // 20, 0.1)[0] is rest and len(step) == 1
    # without frames yet, a pose ahead is kept; the next live pose is a jump back and starts over
    fresh = PoseBuffer()
    assert fresh.add(3700 * S, rest, now=0.0) and fresh.add(100 * S, rest, now=0.1)
    assert fresh.restarts == 1 and len(fresh) == 1 and fresh.lookup(100 * S, 0.1)[0] is rest
    # the pose stream stopped: the refusal says that the newest pose is old
    none, why = fresh.lookup(130 * S, 0.1, now=1000.0)
    assert none is None and "the newest robot pose is stamped 30 s before the frame" in why, why


@pytest.mark.parametrize("back_s", [3600.0, 5.0])
def test_a_clock_step_back_or_looped_bag_starts_the_buffer_over(back_s: float) -> None:
    """Stamps going back (a clock step, a restarted driver, a bag looped three times): the buffer
    starts over, says so, and every capture after it has its pose."""
    buf = PoseBuffer()
    a = Transform.from_rotvec([0, 0, 0.0], [0.0, 0.0, 0.5])
    wall = 0.0
    start = 4000.0
    for loop in range(3):
        got = _frames_and_poses(buf, start - (back_s if loop else 0.0), 30, a, wall0=wall)
        wall += 3.0
        assert all(p is not None for p, _ in got), (loop, got)
    assert buf.restarts == 2 and "jumped back" in buf.stamp_note and "started over" in buf.stamp_note
    assert "started over 2 time(s) on a backward jump" in buf.describe()
    # small disorder (DDS, two callbacks) is not a jump
    before = buf.restarts
    buf.add(int((start - back_s + 2.0) * S), a, now=wall)
    assert buf.restarts == before
    # ~/reset: empty, no notes; the reason of a refusal says nothing was kept
    buf.clear()
    assert len(buf) == 0 and buf.set_aside == 0 and buf.restarts == 0 and buf.stamp_note == ""
    none, why = buf.lookup(int(start * S), 0.1)
    assert none is None and "none kept of" in why
    assert "0 sample(s)" in buf.describe()
    # a recorded bag read whole keeps every sample, in any order (jump_back_s=None)
    whole = PoseBuffer(horizon_s=100.0, jump_back_s=None)
    for t in (50, 10, 40, 20):
        whole.add(t * S, a)
    assert len(whole) == 4 and whole.restarts == 0


def test_robot_motion_between_frames_refuses_them(frames: dict[str, Detection]) -> None:
    buf = PoseBuffer()
    rest = Transform.from_rotvec([0.1, 0.2, 0.3], [0.4, 0.0, 0.5])
    for k in range(11):  # at rest over 0..0.5 s at 20 Hz
        buf.add(k * S // 20, rest)
    moved = rest @ Transform.from_rotvec([0, 0, 0], [0.0, 0.0, 0.001])  # 1 mm
    buf.add(11 * S // 20, moved)
    buf.add(12 * S // 20, rest)  # ... and back: the motion between two frames still counts
    assert buf.motion_between(0, 10 * S // 20, 0.1) == (0.0, 0.0)
    mm, deg = buf.motion_between(10 * S // 20, 12 * S // 20, 0.1)  # type: ignore[misc]
    assert abs(mm - 1.0) < 1e-9 and deg < 1e-9
    gate = StillnessGate(max_motion_px=0.5)
    gate.examine(frames["a"], 0, buf, 0.1)
    v = gate.examine(frames["b"], 10 * S // 20, buf, 0.1)
    assert v.usable and v.robot_pose is not None and v.robot_still is True
    np.testing.assert_allclose(v.robot_pose.translation, rest.translation)
    v = gate.examine(frames["b"], 12 * S // 20, buf, 0.1)  # the image is still, the robot was not
    assert not v.usable and v.moving and "robot moved 1.00 mm" in v.reason and v.robot_still is False
    # a frame without a pose at its stamp
    v = gate.examine(frames["b"], 3 * S, buf, 0.1)
    assert not v.usable and v.reason.startswith("no robot pose")


def test_capture_decisions() -> None:
    assert capture_is_final(Verdict(True), True)
    assert not capture_is_final(Verdict(False, Rejection(RejectionKind.MOVING, "moving (target moved 2 px)")), True)
    assert capture_is_final(Verdict(False, Rejection(RejectionKind.NO_POSE, "no robot pose (none received yet)")), True)
    # a failed detection decides if the robot is known to rest, or without robot poses
    target, blurred = Rejection(RejectionKind.TARGET, "no target found"), Rejection(RejectionKind.TARGET, "too blurred")
    assert capture_is_final(Verdict(False, target, robot_still=True), True)
    assert not capture_is_final(Verdict(False, blurred, robot_still=False), True)
    assert not capture_is_final(Verdict(False, blurred, robot_still=None), True)
    assert capture_is_final(Verdict(False, blurred), False)


def test_capture_slot_bookkeeping() -> None:
    slot = CaptureSlot()
    c = slot.open(5.0, now=100.0)
    assert c is not None and slot.open(5.0) is None  # one at a time
    assert slot.for_frame(99.9) is None  # received before the request: not "the next frame"
    assert slot.for_frame(100.1) is c
    assert slot.finish(c, True, "view 0 stored")
    assert not slot.finish(c, False, "late")  # answered once
    assert slot.wait(c, 5.0) == (True, "view 0 stored") and slot.stored == 1
    assert slot.for_frame(101.0) is None
    # timeout: answered with the last reason
    c = slot.open(0.2)
    assert c is not None
    slot.note(c, "moving (target moved 2.00 px between frames; max_motion_px 0.5)")
    t0 = time.monotonic()
    ok, msg = slot.wait(c, 0.2)
    assert not ok and 0.15 < time.monotonic() - t0 < 2.0
    assert "nothing stored within 0.2 s" in msg and "1 examined" in msg and "moving" in msg, msg
    assert slot.refused == 1 and slot.pending is None
    c = slot.open(0.1)
    assert c is not None and "no frame arrived" in slot.wait(c, 0.1)[1]
    # answered from another thread while waiting
    c = slot.open(5.0)
    assert c is not None
    threading.Timer(0.05, lambda: slot.finish(c, True, "view 1 stored")).start()
    assert slot.wait(c, 5.0) == (True, "view 1 stored")


def test_capture_stores_a_view_like_a_stored_one(frames: dict[str, Detection]) -> None:
    col = ViewCollector(min_views=3)
    pose = Transform.from_rotvec([0, 0, 0.1], [0.4, 0.1, 0.5])
    assert col.offer(frames["a"], pose)[0]
    assert not col.offer(frames["b"])[0]  # too similar for automatic collection
    assert col.offer(frames["b"], pose, force=True)[0]  # a capture stores it
    assert col.robot_poses == [pose, pose] and len(col.views) == 2
    msg = stored_message(1, frames["b"], pose)
    assert msg.startswith("view 1 stored: target at (4") and " px, tilt " in msg and "robot tool at [0.4000" in msg
    col.clear()
    assert col.robot_poses == [] and col.views == []
