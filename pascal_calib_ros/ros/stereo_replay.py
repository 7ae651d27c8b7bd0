"""``replay_node``'s stereo replays: two folders (``left_source``, ``right_source``) or a bag's two
image topics (``source`` with ``left_bag_topic`` and ``right_bag_topic``), shot by shot, for the
calibration node's stereo mode.

Folders are paired as ``pascal-calib stereo`` pairs them (:func:`~..workflows.stereo.pair_files`:
by file stem, else by the number in the file names, else by sorted order); a bag's frames by their
recorded header stamps within ``sync_slop`` (:class:`~..session.frame_pairing.ApproximatePairer`,
the calibration node's pairing). Files or frames without a partner are skipped and counted: they
would never pair. Each shot's two frames go out with one stamp (taken at publication), so the node
pairs them whatever its ``sync_slop``; in lock-step the next shot waits until the node has
acknowledged both frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Header

from ..errors import PascalCalibError
from ..io import (
    COMPRESSED_TYPE,
    BagImage,
    ImageReadError,
    grey_to_image_fields,
    image_topics,
    read_grey,
    read_image_topics,
)
from ..session import SIDES, ApproximatePairer
from ..workflows import PairingError, expand_glob, pair_files

STEREO_PARAMS: tuple[tuple[str, Any, str], ...] = (
    ("left_source", "", "stereo: the left camera's folder or glob of images (with right_source; shots paired as "
                        "`pascal-calib stereo` pairs them: by file stem, else by the number in the file names, else "
                        "by sorted order; files without a partner are skipped)"),
    ("right_source", "", "stereo: the right camera's folder or glob of images"),
    ("left_bag_topic", "", "stereo from the bag in source: the left camera's image topic (with right_bag_topic)"),
    ("right_bag_topic", "", "stereo from the bag in source: the right camera's image topic"),
    ("left_topic", "left/image", "stereo: output topic of the left frames (compressed: <topic>/compressed)"),
    ("right_topic", "right/image", "stereo: output topic of the right frames (compressed: <topic>/compressed)"),
    ("sync_slop", 0.02, "stereo bags: a left and a right frame whose recorded stamps differ by at most this many "
                        "seconds form a shot; frames without a partner are skipped and counted"),
)
FRAME_IDS = ("left_camera_optical_frame", "right_camera_optical_frame")  # a folder's frames (the node's defaults)


class StereoReplayError(PascalCalibError):
    """A stereo replay that cannot work (its parameters or sources)."""


@dataclass
class StereoShot:
    name: str
    frames: tuple[Any, Any]  # image file paths, or BagImages
    recorded_ns: int = 0  # bags: the left frame's recorded time


def requested(p: Callable[[str], Any]) -> bool:
    """Whether the parameters ask for a stereo replay; a :class:`StereoReplayError` when they ask
    for half of one or mix it with single-camera parameters."""
    folders = [bool(p("left_source")), bool(p("right_source"))]
    topics = [bool(p("left_bag_topic")), bool(p("right_bag_topic"))]
    if any(folders) and not all(folders):
        raise StereoReplayError("a stereo replay of folders needs both left_source and right_source")
    if any(topics) and not all(topics):
        raise StereoReplayError("a stereo replay of a bag needs both left_bag_topic and right_bag_topic")
    if all(folders) and all(topics):
        raise StereoReplayError("give either left_source and right_source (folders) or source with left_bag_topic "
                                "and right_bag_topic (a bag), not both")
    if not (all(folders) or all(topics)):
        return False
    if all(folders) and p("source"):
        raise StereoReplayError("source is for one camera or a bag; with left_source and right_source leave it empty")
    if all(topics) and not p("source"):
        raise StereoReplayError("left_bag_topic and right_bag_topic need the bag in source")
    for name in ("pose_topic", "frame_id", "bag_topic"):
        if p(name):
            raise StereoReplayError(f"{name} is not used by a stereo replay (frame ids: the bag's, else "
                                    f"{FRAME_IDS[0]} and {FRAME_IDS[1]})")
    if float(p("sync_slop")) < 0:
        raise StereoReplayError(f"sync_slop must be 0 or more seconds, got {p('sync_slop')}")
    return True


class StereoSource:
    """The shots of a stereo replay (module docstring)."""

    def __init__(self, p: Callable[[str], Any], bag: Path | None) -> None:
        self.p, self.bag = p, bag
        self.skipped = 0  # frames or files without a partner
        if bag is None:
            groups = [expand_glob(str(p(f"{side}_source"))) for side in SIDES]
            try:
                self.pairing = pair_files(groups, list(SIDES))
            except PairingError as e:
                raise StereoReplayError(str(e)) from None
            self.compressed = (p("transport") == "compressed",) * 2
            n = sum(1 for k in range(len(self.pairing.shots)) if None not in (self.pairing.paths[0][k],
                                                                                self.pairing.paths[1][k]))
            self.what = (f"{n} stereo shot(s) from {p('left_source')} and {p('right_source')} (paired "
                         f"{self.pairing.how})")
        else:
            self.topics = (str(p("left_bag_topic")), str(p("right_bag_topic")))
            types = image_topics(bag)
            missing = [t for t in self.topics if t not in types]
            if missing:
                raise StereoReplayError(f"bag {bag} has no image topic {', '.join(missing)}; it has "
                                        f"{', '.join(sorted(types)) or 'none'}")
            self.compressed = (types[self.topics[0]] == COMPRESSED_TYPE, types[self.topics[1]] == COMPRESSED_TYPE)
            self.what = f"stereo bag {bag} ({self.topics[0]}, {self.topics[1]}; pairs within {p('sync_slop')} s)"

    def shots(self) -> Iterator[StereoShot]:
        if self.bag is None:
            pr = self.pairing
            for k, name in enumerate(pr.shots):
                left, right = pr.paths[0][k], pr.paths[1][k]
                if left is None or right is None:
                    self.skipped += 1
                    continue
                yield StereoShot(name, (left, right))
            return
        pairer = ApproximatePairer(float(self.p("sync_slop")), queue_size=32)
        for side, item in read_image_topics(self.bag, self.topics):
            pairs, dropped = pairer.push(side, item.stamp_ns or item.timestamp_ns, item)
            self.skipped += len(dropped)
            for a, b in pairs:
                yield StereoShot(f"stereo pair {pairer.stats.paired}", (a.item, b.item), a.item.timestamp_ns)
        self.skipped += len(pairer.clear())

    def message(self, side: int, frame: Any, stamp: Any) -> Image | CompressedImage | None:
        """The message of one frame (None: an unreadable file, logged by the caller)."""
        if isinstance(frame, BagImage):
            header = Header(stamp=stamp, frame_id=frame.frame_id or FRAME_IDS[side])
            f = frame.fields
            if frame.msgtype == COMPRESSED_TYPE:
                msg: Any = CompressedImage(header=header, format=f["format"])
            else:
                msg = Image(header=header, height=f["height"], width=f["width"], encoding=f["encoding"],
                            is_bigendian=f["is_bigendian"], step=f["step"])
            msg.data = f["data"]
            return msg
        header = Header(stamp=stamp, frame_id=FRAME_IDS[side])
        path = Path(frame)
        if self.compressed[side]:
            out = CompressedImage(header=header, format="png" if path.suffix.lower() == ".png" else "jpeg")
            out.data = path.read_bytes()
            return out
        try:
            return Image(header=header, **grey_to_image_fields(read_grey(path)))
        except ImageReadError:
            return None


def stereo_publishers(node: Any, source: StereoSource, output_topic: Callable[[str, bool], tuple[str, str]]
                      ) -> tuple[Any, Any]:
    """The left and the right image publisher (the replay's QoS; each side's message type)."""
    qos = QoSProfile(depth=5, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE if node.p("qos") == "reliable"
                     else ReliabilityPolicy.BEST_EFFORT)
    pubs = []
    for c, side in enumerate(SIDES):
        topic, warning = output_topic(str(node.p(f"{side}_topic")), source.compressed[c])
        if warning:
            node.get_logger().warn(warning)
        pubs.append(node.create_publisher(CompressedImage if source.compressed[c] else Image, topic, qos))
    if pubs[0].topic_name == pubs[1].topic_name:
        raise StereoReplayError(f"left_topic and right_topic both publish on {pubs[0].topic_name}")
    return pubs[0], pubs[1]


def replay_stereo(node: Any) -> None:
    """One pass over the shots of ``node.stereo``: both frames of a shot with one stamp; timed at
    ``rate`` shots per second (0: the bag's recorded timing), or lock-step."""
    src: StereoSource = node.stereo
    timed, rate = node.mode == "timed", float(node.p("rate"))
    t_start, t0 = time.monotonic(), None
    for k, shot in enumerate(src.shots()):
        if node.done.is_set():
            return
        if timed and rate > 0:
            node._sleep_until(t_start + k / rate)
        elif timed:
            t0 = shot.recorded_ns if t0 is None else t0
            node._sleep_until(t_start + (shot.recorded_ns - t0) * 1e-9)
        stamp = node.get_clock().now().to_msg()
        msgs = [src.message(c, shot.frames[c], stamp) for c in (0, 1)]
        if msgs[0] is None or msgs[1] is None:
            node.get_logger().warn(f"skipped {shot.name}: an image file cannot be read")
            src.skipped += 2
            continue
        node._publish_group(list(zip(node.pubs, msgs, strict=True)), shot.name)
