"""Still views of a recorded robot-arm session (rosbag2) for offline hand-eye calibration.

``pascal-calib handeye --bag``: the bag holds the camera images and the robot's tool poses
(geometry_msgs/PoseStamped or TransformStamped) as recorded while the arm moved through its poses
and rested at each. Every image gets the robot pose at its stamp as the calibration node finds it
(:meth:`~.arm_session.PoseBuffer.lookup`: interpolated between the two nearest samples, refused
if none lies within ``pose_max_age``). A frame is *still* if the robot pose did not change over
the pose samples around its stamp (the last one before and the first one after it, within
``pose_max_age``); consecutive still frames with the same robot pose (within :data:`STILL_M` /
:data:`STILL_RAD`; a driver repeats the pose while the arm rests) are one rest of the arm, and
the middle frame of each rest is used. Stamps are the header stamps (the recording time if a
header has none).
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..geometry import Transform, TransformError
from ..io import (
    COMPRESSED_TYPE,
    POSE_TYPE,
    BagError,
    BagImage,
    BagPose,
    ImageConversionError,
    compressed_to_grey,
    image_to_grey,
    image_topics,
    pose_topics,
    read_session,
)
from .arm_session import PoseBuffer

STILL_M = 1e-6  # the robot rests if its pose changes by at most this (translation) ...
STILL_RAD = 1e-6  # ... and this (rotation) over the samples around a frame
DEFAULT_TOOL_FRAME = "tool0"  # PoseStamped has no child frame
DEFAULT_BASE_FRAME = "base_link"  # a pose message without header.frame_id
SAME_REST = "same rest of the arm as a used frame"
ROBOT_MOVING = "robot moving"


@dataclass
class BagFrame:
    """One image of the bag and what it is used for."""

    index: int  # among the image topic's messages, from 0
    stamp_ns: int
    name: str
    pose: Transform | None = None  # T_base_tool at the stamp
    reason: str = ""  # why it is skipped; empty if used


@dataclass
class ArmBag:
    """The frames of an arm session bag, each used or skipped with the reason."""

    path: Path
    image_topic: str
    pose_topic: str
    pose_type: str
    frame_id: str  # the robot base
    child_frame_id: str  # the tool
    poses_read: int
    frames: list[BagFrame] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def used(self) -> list[BagFrame]:
        return [f for f in self.frames if not f.reason]

    def summary(self) -> str:
        """What was read, used and skipped (and why)."""
        kind = self.pose_type.rsplit("/", 1)[-1]
        lines = [f"bag {self.path}: {len(self.frames)} frame(s) on {self.image_topic}, {self.poses_read} robot "
                 f"pose(s) on {self.pose_topic} ({kind}, {self.frame_id} -> {self.child_frame_id})"]
        lines += [f"note: {n}" for n in self.notes]
        lines.append(f"frames used: {len(self.used)} (one per rest of the arm: the middle of each run of still "
                     "frames with the same robot pose)")
        skipped = [f for f in self.frames if f.reason]
        if skipped:
            groups: dict[str, list[BagFrame]] = {}
            for f in skipped:
                groups.setdefault(f.reason.split(" (")[0], []).append(f)
            parts = []
            for key, fs in groups.items():
                detail = fs[0].reason[len(key):].strip(" ()")
                example = f" (e.g. {fs[0].name}: {detail})" if detail and key != SAME_REST else ""
                parts.append(f"{len(fs)} {key}{example}")
            lines.append(f"frames skipped: {len(skipped)}: " + "; ".join(parts))
        return "\n".join(lines)

    def images(self) -> Iterator[tuple[BagFrame, np.ndarray | str]]:
        """The used frames, decoded to grey (or the reason they cannot be), in recorded order:
        a second pass over the bag, so only these images are held."""
        wanted = {f.index: f for f in self.used}
        last = max(wanted, default=-1)
        k = -1
        for item in read_session(self.path, self.image_topic, self.pose_topic):
            if not isinstance(item, BagImage):
                continue
            k += 1
            if k in wanted:
                yield wanted[k], _decode(item)
            if k >= last:
                return


def _decode(item: BagImage) -> np.ndarray | str:
    msg = SimpleNamespace(**item.fields)
    try:
        return compressed_to_grey(msg) if item.msgtype == COMPRESSED_TYPE else image_to_grey(msg)
    except ImageConversionError as e:
        return str(e)


def _stamp(item: BagImage | BagPose) -> int:
    """The header stamp, the recording time if the header has none (as the replay node)."""
    return item.stamp_ns or item.timestamp_ns


def _all_topics(path: Path) -> dict[str, str]:
    from rosbags.rosbag2 import Reader

    try:
        with Reader(path) as reader:
            return {c.topic: c.msgtype for c in reader.connections}
    except Exception as e:  # rosbags raises several types for unreadable bags
        raise BagError(f"cannot open bag {path}: {e}") from None


def _listing(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"


def resolve_topics(path: str | Path, image_topic: str = "", pose_topic: str = "") -> tuple[str, str, str]:
    """(image topic, pose topic, pose message type) of an arm session bag; a topic left empty is
    the bag's only suitable one. :class:`BagError` says what is missing and lists the topics."""
    p = Path(path)
    if not p.exists():
        raise BagError(f"bag not found: {p}")
    every = _all_topics(p)
    images, poses = image_topics(p), pose_topics(p)
    if image_topic:
        if image_topic not in images:
            what = f"is a {every[image_topic]}, not an image" if image_topic in every else "does not exist"
            raise BagError(f"bag {p}: image topic {image_topic!r} {what}; topics: {_listing(every)}")
    elif len(images) != 1:
        raise BagError(f"bag {p} has no sensor_msgs/Image or CompressedImage topic; topics: {_listing(every)}"
                       if not images else
                       f"bag {p} has {len(images)} image topics; choose one with --image-topic: {_listing(images)}")
    else:
        image_topic = next(iter(images))
    if pose_topic:
        if pose_topic not in poses:
            what = (f"is a {every[pose_topic]}, not a geometry_msgs/PoseStamped or TransformStamped"
                    if pose_topic in every else "does not exist")
            raise BagError(f"bag {p}: pose topic {pose_topic!r} {what}; topics: {_listing(every)}")
    elif len(poses) != 1:
        raise BagError(f"bag {p} has no geometry_msgs/PoseStamped or TransformStamped topic (the robot's tool "
                       f"pose); topics: {_listing(every)}" if not poses else
                       f"bag {p} has {len(poses)} pose topics; choose one with --pose-topic: {_listing(poses)}")
    else:
        pose_topic = next(iter(poses))
    return image_topic, pose_topic, poses[pose_topic]


def read_arm_bag(path: str | Path, image_topic: str = "", pose_topic: str = "", pose_max_age: float = 0.1,
                 tool_frame: str = "") -> ArmBag:
    """The frames of an arm session bag with their robot poses, one still frame used per rest
    (module docstring). ``tool_frame`` names the tool of PoseStamped poses (default
    :data:`DEFAULT_TOOL_FRAME`); for TransformStamped it must match child_frame_id if given.
    A pose that is not a rigid transform is ignored (noted). Raises :class:`BagError` for a
    missing or unsuitable bag, inconsistent pose frames, and when no frame has a robot pose within
    ``pose_max_age``."""
    if not pose_max_age >= 0:
        raise BagError(f"pose_max_age must be >= 0 s, got {pose_max_age:g}")
    p = Path(path)
    image_topic, pose_topic, pose_type = resolve_topics(p, image_topic, pose_topic)
    samples: list[tuple[int, Transform]] = []
    frames_seen: dict[tuple[str, str], int] = {}
    stamps: list[int] = []
    bad: list[str] = []
    for item in read_session(p, image_topic, pose_topic):
        if isinstance(item, BagImage):
            stamps.append(_stamp(item))
            continue
        key = (item.frame_id.lstrip("/"), item.child_frame_id.lstrip("/"))
        frames_seen[key] = frames_seen.get(key, 0) + 1
        try:
            samples.append((_stamp(item), Transform.from_quat(item.rotation, item.translation)))
        except TransformError as e:  # ignored, as the node does
            bad.append(f"stamp {_stamp(item)} ns: {e}")
    if not stamps:
        raise BagError(f"bag {p}: no message on image topic {image_topic}")
    if not samples:
        raise BagError(f"bag {p}: no usable message on pose topic {pose_topic}"
                       + (f" ({len(bad)} not a rigid transform, e.g. {bad[0]})" if bad else ""))
    if len(frames_seen) > 1:
        seen = ", ".join(f"{b or '?'} -> {c or '?'} ({n})" for (b, c), n in frames_seen.items())
        raise BagError(f"bag {p}: the poses on {pose_topic} change frames ({seen}); one base and tool expected")
    (base, child), = frames_seen
    notes = [f"{len(bad)} pose message(s) ignored, not a rigid transform (e.g. {bad[0]})"] if bad else []
    if not base:
        base = DEFAULT_BASE_FRAME
        notes.append(f"the pose messages have no header.frame_id: the base frame is called {base}")
    if pose_type == POSE_TYPE:
        child = tool_frame or DEFAULT_TOOL_FRAME
        if not tool_frame:
            notes.append(f"PoseStamped names no tool frame: {child} (set --tool-frame)")
    elif tool_frame and child != tool_frame:
        raise BagError(f"bag {p}: the poses on {pose_topic} are {base} -> {child}, not -> {tool_frame} "
                       "(--tool-frame)")
    elif not child:
        child = DEFAULT_TOOL_FRAME
        notes.append(f"the TransformStamped poses have no child_frame_id: the tool frame is called {child}")

    span_s = (max(s for s, _ in samples) - min(s for s, _ in samples)) * 1e-9
    buffer = PoseBuffer(horizon_s=span_s + 1.0, max_samples=len(samples) + 1, jump_back_s=None)  # keeps every sample
    for s, T in samples:
        buffer.add(s, T)
    sample_stamps = sorted({s for s, _ in samples})
    t0 = min(stamps)
    out = ArmBag(p, image_topic, pose_topic, pose_type, base, child, len(samples), notes=notes)
    for k, t in enumerate(stamps):
        out.frames.append(_examine(BagFrame(k, t, f"frame_{k:04d}@{(t - t0) * 1e-9:.2f}s"), buffer,
                                   sample_stamps, pose_max_age))
    if all(f.pose is None for f in out.frames):
        raise BagError(f"bag {p}: no frame has a robot pose within pose_max_age {pose_max_age:g} s of its stamp "
                       f"(e.g. {out.frames[0].name}: {out.frames[0].reason}); are the image and pose stamps "
                       "from the same clock?")
    _pick_rests(out.frames)
    return out


def _examine(frame: BagFrame, buffer: PoseBuffer, sample_stamps: list[int], max_age_s: float) -> BagFrame:
    """The robot pose at the frame's stamp and whether the robot moved around it."""
    t = frame.stamp_ns
    pose, why = buffer.lookup(t, max_age_s)
    if pose is None:
        frame.reason = why
        return frame
    frame.pose = pose
    max_age = int(max_age_s * 1e9)
    i, j = bisect.bisect_left(sample_stamps, t), bisect.bisect_right(sample_stamps, t)
    lo = sample_stamps[i - 1] if i > 0 and t - sample_stamps[i - 1] <= max_age else t
    hi = sample_stamps[j] if j < len(sample_stamps) and sample_stamps[j] - t <= max_age else t
    moved = buffer.motion_between(lo, hi, max_age_s)
    if moved is None or moved[0] > 1000 * STILL_M or moved[1] > np.degrees(STILL_RAD):
        mm, deg = moved if moved is not None else (float("nan"), float("nan"))
        frame.reason = f"{ROBOT_MOVING} (pose changes by {mm:.3f} mm, {deg:.4f} deg between the samples around it)"
    return frame


def _same_pose(a: Transform, b: Transform) -> bool:
    return (float(np.linalg.norm(a.translation - b.translation)) <= STILL_M
            and float((a.rotation.inv() * b.rotation).magnitude()) <= STILL_RAD)


def _pick_rests(frames: list[BagFrame]) -> None:
    """Mark all but the middle frame of each run of consecutive still frames with one pose."""
    runs: list[list[BagFrame]] = []
    run_pose: Transform | None = None  # the pose of the open run; None after a skipped frame
    for f in frames:
        if f.reason or f.pose is None:
            run_pose = None
            continue
        if run_pose is not None and _same_pose(run_pose, f.pose):
            runs[-1].append(f)
        else:
            runs.append([f])
            run_pose = f.pose
    for run in runs:
        keep = run[len(run) // 2]
        for f in run:
            if f is not keep:
                f.reason = f"{SAME_REST} ({keep.name})"
