"""ROS 2 image replay node ``image_replay`` (executable ``replay_node``).

Publishes a folder or glob of image files, or the images of a rosbag2 bag (sqlite3 or mcap), as
sensor_msgs/Image on ``topic`` or sensor_msgs/CompressedImage on ``<topic>/compressed`` (or on
``topic`` itself if it already ends in ``/compressed``), with headers stamped at publication time.

Two modes:

* ``lockstep`` (default): the next frame is published only once the calibration node has
  examined the previous one. The node publishes the header of every frame its detector has
  finished with on ``~/examined_frames`` (std_msgs/Header, reliable, transient local); the
  replay waits for the header whose stamp is the one it just published (stamps are unique: taken
  at publication). No frame is dropped by a busy detector, so a replay gives the same views on
  a fast and on a slow machine. A frame not acknowledged within ``ack_timeout`` stops the
  replay with an error (exit code 1).
* ``timed``: publish at ``rate`` Hz (or the recorded timing of a bag with ``rate`` 0) without
  waiting: load tests; a busy node drops frames (and says so in its status).

Robot-arm sessions: with ``pose_topic`` the bag's robot poses (geometry_msgs/PoseStamped or
TransformStamped) are replayed too, on the same topic name, and every message keeps its recorded
stamp shifted by one offset per pass (the start of the pass), so image and pose stamps keep their
recorded relation and the calibration node finds each frame's pose as recorded. Before each image
every pose whose stamp is at most ``pose_lead`` seconds after the image's goes out (lock-step: the
pose of a frame, and the next one for interpolation, always precede it; timed: poses are otherwise
sent at their recorded time).

For recording once and calibrating later, see ``pascal-calib bag`` (a folder of images into a bag;
with ``--poses POSES.yaml`` an arm session with its robot poses).
"""

from __future__ import annotations

import glob
import threading
import time
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Header

from ..errors import PascalCalibError
from ..io import (
    COMPRESSED_TYPE,
    IMAGE_SUFFIXES,
    POSE_TYPE,
    BagError,
    BagImage,
    BagPose,
    ImageReadError,
    grey_to_image_fields,
    pose_topics,
    read_grey,
    read_session,
)
from .guard import guarded_callback
from .stereo_replay import STEREO_PARAMS, StereoReplayError, StereoSource, replay_stereo, requested, stereo_publishers

PARAMS: tuple[tuple[str, Any, str], ...] = (
    ("source", "", "folder, glob of image files, or rosbag2 bag folder/file"),
    ("bag_topic", "", "image topic to replay from a bag (needed when it has several)"),
    ("pose_topic", "", "bags: also replay this robot pose topic (geometry_msgs/PoseStamped or TransformStamped) "
                       "under its own name, stamps as recorded (shifted to the present)"),
    ("pose_lead", 0.1, "with pose_topic: poses stamped up to this many seconds after an image go out before it"),
    ("topic", "image", "output topic (compressed images go to <topic>/compressed, or to topic itself if it "
                       "ends in /compressed)"),
    ("mode", "lockstep", "lockstep: publish the next frame once the calibration node has examined the previous "
                         "one (ack_topic; no frame dropped, reproducible on any machine) | timed: publish at "
                         "rate (load tests; a busy node drops frames)"),
    ("ack_topic", "/pascal_calib/examined_frames", "lockstep: the calibration node's examined-frame topic "
                                                   "(std_msgs/Header)"),
    ("ack_timeout", 30.0, "lockstep: seconds to wait for the calibration node to appear and for each frame "
                          "to be examined before stopping with an error"),
    ("rate", 2.0, "timed mode: messages per second; 0 = recorded timing (bags only)"),
    ("loop", False, "start again at the end"),
    ("frame_id", "", "header frame_id; empty: the bag's, else 'camera'"),
    ("start_delay", 0.0, "seconds to wait before the first message"),
    ("wait_for_subscribers", 0, "wait (up to 30 s) until this many subscribers are matched, then 0.5 s"),
    ("exit_when_done", False, "shut down after the last message (ignored with loop)"),
    ("qos", "reliable", "reliable | best_effort"),
    ("transport", "raw", "folders: raw (decode to Image) | compressed (file bytes as CompressedImage)"),
    *STEREO_PARAMS,
)


class ReplayError(PascalCalibError):
    pass


class ReplayNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("image_replay", **kwargs)
        self._declare()
        self.mode = str(self.p("mode"))
        self.stereo: StereoSource | None = None
        self.pubs: tuple[Any, ...]
        self.pub_pose: Any = None
        if requested(self.p):  # two cameras (stereo_replay.py)
            self.stereo = StereoSource(self.p, self._bag_path() if self.source else None)
            compressed, what = any(self.stereo.compressed), self.stereo.what
            self.pose_topic, self.poses_published = "", 0
            self.pubs = stereo_publishers(self, self.stereo, output_topic)
        else:
            compressed, what = self._open_source()
            what += self._pose_publisher()
            self.pubs = (self._image_publisher(compressed),)
        self.pub = self.pubs[0]
        self.published = 0
        self.acknowledged = 0
        self.failed = False  # lock-step gave up: main() exits with 1
        self.done = threading.Event()
        self._acks: deque[tuple[int, int, str]] = deque(maxlen=64)
        self._ack_cv = threading.Condition()
        self.ack_topic = ""
        if self.mode == "lockstep":
            self.ack_topic = self.resolve_topic_name(str(self.p("ack_topic")))
            ack_qos = QoSProfile(depth=5, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self.sub_ack = self.create_subscription(Header, self.ack_topic,
                                                    guarded_callback(self, "acknowledgement", self._on_ack), ack_qos)
            how = (f"lock-step: each frame once {self.ack_topic} acknowledges the previous "
                   f"(timeout {float(self.p('ack_timeout')):g} s; rate ignored)")
        else:
            rate = float(self.p("rate"))
            how = f"timed: {rate:g} Hz" if rate > 0 else "timed: recorded timing"
        kind = "sensor_msgs/CompressedImage" if compressed else "sensor_msgs/Image"
        self.topics = ", ".join(p.topic_name for p in self.pubs)
        self.get_logger().info(f"replaying {what} as {kind} on {self.topics} ({self.p('qos')}); {how}")
        if self.mode == "lockstep" and self.p("qos") == "best_effort":
            self.get_logger().warn("lock-step over best-effort QoS: a lost frame stops the replay after "
                                   "ack_timeout; use qos:=reliable")
        self._thread = threading.Thread(target=self._run, name="replay", daemon=True)
        self._thread.start()

    def _declare(self) -> None:
        """Declare the parameters (read only) and refuse values that cannot work."""
        for name, default, desc in PARAMS:
            d = ParameterDescriptor(description=desc, read_only=True)
            if name in ("rate", "start_delay", "pose_lead", "sync_slop"):
                d.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=1000.0, step=0.0)]
            if name == "ack_timeout":
                d.floating_point_range = [FloatingPointRange(from_value=0.1, to_value=3600.0, step=0.0)]
            self.declare_parameter(name, default, d)
        self.source = str(self.p("source"))
        if not self.source and not (self.p("left_source") or self.p("right_source")):
            raise ReplayError("parameter 'source' is empty: give a folder, a glob or a bag (stereo: left_source and "
                              "right_source)")
        if self.p("qos") not in ("reliable", "best_effort"):
            raise ReplayError(f"qos must be reliable or best_effort, got {self.p('qos')!r}")
        if self.p("transport") not in ("raw", "compressed"):
            raise ReplayError(f"transport must be raw or compressed, got {self.p('transport')!r}")
        if self.p("mode") not in ("lockstep", "timed"):
            raise ReplayError(f"mode must be lockstep or timed, got {self.p('mode')!r}")

    def _open_source(self) -> tuple[bool, str]:
        """(compressed frames, what is replayed); a missing or corrupt source fails here, at start."""
        self.is_bag = self._looks_like_bag(self.source)
        self.files: list[Path] = []
        if not self.is_bag:
            self.files = self._image_files(self.source)
            if self.mode == "timed" and float(self.p("rate")) <= 0:
                raise ReplayError("rate 0 (recorded timing) needs a bag; set rate > 0 for image files")
            return self.p("transport") == "compressed", f"{len(self.files)} image file(s) from {self.source}"
        first = next((x for x in self._bag_items() if isinstance(x, BagImage)), None)
        if first is None:
            raise ReplayError(f"bag {self.source} has no image messages")
        return (first.msgtype == COMPRESSED_TYPE,
                f"bag {self.source}" + (f" ({self.p('bag_topic')})" if self.p("bag_topic") else ""))

    def _pose_publisher(self) -> str:
        """The robot pose publisher of a bag with ``pose_topic``; what it adds to the log line."""
        self.pose_topic = str(self.p("pose_topic"))
        self.poses_published = 0
        if not self.pose_topic:
            return ""
        if not self.is_bag:
            raise ReplayError("pose_topic needs a bag as source (image folders carry no robot poses)")
        pose_type = pose_topics(self._bag_path()).get(self.pose_topic)
        if pose_type is None:
            list(read_session(self._bag_path(), str(self.p("bag_topic")), self.pose_topic))  # raises the reason
            raise ReplayError(f"bag {self.source} has no pose topic {self.pose_topic!r}")
        from geometry_msgs.msg import PoseStamped, TransformStamped

        self.pose_msg_type = PoseStamped if pose_type == POSE_TYPE else TransformStamped
        pose_qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
        self.pub_pose = self.create_publisher(self.pose_msg_type, self.pose_topic, pose_qos)
        return f" with robot poses {self.pose_topic} ({pose_type})"

    def _image_publisher(self, compressed: bool) -> Any:
        qos = QoSProfile(depth=5, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE if self.p("qos") == "reliable"
                         else ReliabilityPolicy.BEST_EFFORT)
        topic, warning = output_topic(str(self.p("topic")), compressed)
        if warning:
            self.get_logger().warn(warning)
        self.pub_raw: Any = None
        self.pub_compressed: Any = None
        if compressed:
            self.pub_compressed = self.create_publisher(CompressedImage, topic, qos)
        else:
            self.pub_raw = self.create_publisher(Image, topic, qos)
        return self.pub_compressed if compressed else self.pub_raw

    def p(self, name: str) -> Any:
        return self.get_parameter(name).value

    @staticmethod
    def _looks_like_bag(src: str) -> bool:
        p = Path(src)
        return (p.is_dir() and (p / "metadata.yaml").exists()) or p.suffix in (".mcap", ".db3")

    @staticmethod
    def _image_files(src: str) -> list[Path]:
        p = Path(src)
        if p.is_dir():
            files = sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES)
        else:
            files = sorted(Path(f) for f in glob.glob(src) if Path(f).suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise ReplayError(f"no image files at {src!r}")
        return files

    def _bag_path(self) -> Path:
        path = Path(self.source)
        return path.parent if path.suffix in (".mcap", ".db3") else path

    def _bag_items(self) -> Iterator[Any]:
        return read_session(self._bag_path(), str(self.p("bag_topic")), str(self.p("pose_topic")))

    def _header(self, frame_id: str = "") -> Header:
        fid = str(self.p("frame_id")) or frame_id or "camera"
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=fid)

    def _wait_for_subscribers(self) -> None:
        want = int(self.p("wait_for_subscribers"))
        deadline = time.monotonic() + 30.0
        while want > 0 and time.monotonic() < deadline and not self.done.is_set():
            if min(p.get_subscription_count() for p in self.pubs) >= want and (
                    self.pub_pose is None or self.pub_pose.get_subscription_count() > 0):
                # the publisher sees the subscriber before the subscriber has matched the
                # publisher; messages sent in between can be lost: let discovery settle
                time.sleep(0.5)
                return
            time.sleep(0.05)

    # -- lock-step ------------------------------------------------------------------------
    def _on_ack(self, msg: Header) -> None:
        with self._ack_cv:
            self._acks.append((msg.stamp.sec, msg.stamp.nanosec, msg.frame_id))
            self._ack_cv.notify_all()

    def _wait_for_calibration_node(self) -> None:
        """Lock-step: wait until the node's image subscription and its acknowledgements are
        matched (then let discovery settle), or fail after ``ack_timeout``."""
        timeout = float(self.p("ack_timeout"))
        t0 = time.monotonic()
        next_log = t0 + 5.0
        while not self.done.is_set():
            if min(p.get_subscription_count() for p in self.pubs) > 0 and self.sub_ack.get_publisher_count() > 0 and (
                    self.pub_pose is None or self.pub_pose.get_subscription_count() > 0):
                time.sleep(0.5)
                return
            now = time.monotonic()
            if now - t0 > timeout:
                raise ReplayError(
                    f"lock-step: no calibration node within {timeout:g} s (subscribers of "
                    + ", ".join(f"{p.topic_name}: {p.get_subscription_count()}" for p in self.pubs) + ", publishers of "
                    f"{self.ack_topic}: {self.sub_ack.get_publisher_count()}"
                    + (f", subscribers of {self.pose_topic}: {self.pub_pose.get_subscription_count()}"
                       if self.pub_pose is not None else "") + "); start calibration_node, "
                    "remap topic / ack_topic to it, or use mode:=timed to publish without acknowledgements")
            if now >= next_log:
                next_log = now + 5.0
                self.get_logger().info(f"lock-step: waiting for a subscriber of {self.topics} and a "
                                       f"publisher of {self.ack_topic}")
            time.sleep(0.05)

    def _publish(self, msg: Any, name: str) -> None:
        """Publish one frame; in lock-step, return once the calibration node has examined it."""
        self._publish_group([(self.pub, msg)], name)

    def _publish_group(self, items: list[tuple[Any, Any]], name: str) -> None:
        """Publish frames that go together (a stereo shot: (publisher, message) per camera); in
        lock-step, return once the calibration node has acknowledged every one of them."""
        for pub, msg in items:
            pub.publish(msg)
        self.published += len(items)
        if self.mode != "lockstep":
            return
        keys = {(m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id) for _, m in items}
        timeout = float(self.p("ack_timeout"))
        deadline = time.monotonic() + timeout
        with self._ack_cv:
            while not keys <= set(self._acks):
                left = deadline - time.monotonic()
                if self.done.is_set():
                    return
                if left <= 0:
                    raise ReplayError(
                        f"lock-step: frame {self.published} ({name}) was not acknowledged on {self.ack_topic} "
                        f"within {timeout:g} s (publishers of it: {self.sub_ack.get_publisher_count()}): the "
                        "calibration node stopped, listens elsewhere, or the frame was lost; stopping the "
                        "replay (raise ack_timeout for a slow node, or use mode:=timed)")
                self._ack_cv.wait(min(left, 0.2))
        self.acknowledged += len(items)

    def _run(self) -> None:
        try:
            time.sleep(float(self.p("start_delay")))
            self._wait_for_subscribers()
            if self.mode == "lockstep":
                self._wait_for_calibration_node()
            while not self.done.is_set():
                if self.stereo is not None:
                    replay_stereo(self)
                elif self.is_bag:
                    self._replay_bag()
                else:
                    self._replay_files()
                if not self.p("loop"):
                    break
            acked = f", {self.acknowledged} examined by the calibration node" if self.mode == "lockstep" else ""
            poses = f", {self.poses_published} pose(s) on {self.pose_topic}" if self.pose_topic else ""
            if self.stereo is not None and self.stereo.skipped:
                poses += f"; {self.stereo.skipped} frame(s) without a partner skipped"
            self.get_logger().info(f"replay finished: {self.published} message(s) on {self.topics}{acked}{poses}")
        except (BagError, ReplayError, StereoReplayError) as e:
            self.failed = True
            self.get_logger().error(str(e))
        finally:
            if self.p("exit_when_done") and not self.done.is_set():
                time.sleep(1.0)  # let reliable subscribers take the last messages
                self.done.set()
                self.context.try_shutdown()

    def _sleep_until(self, t: float) -> None:
        while not self.done.is_set() and time.monotonic() < t:
            time.sleep(min(0.05, max(0.0, t - time.monotonic())))

    def _replay_files(self) -> None:
        timed = self.mode == "timed"
        period = 1.0 / float(self.p("rate")) if timed else 0.0
        t_next = time.monotonic()
        for f in self.files:
            if self.done.is_set():
                return
            if timed:
                self._sleep_until(t_next)
                t_next += period
            msg: Image | CompressedImage
            if self.p("transport") == "compressed":
                msg = CompressedImage(header=self._header(), format="png" if f.suffix.lower() == ".png" else "jpeg")
                msg.data = f.read_bytes()
            else:
                try:
                    img = read_grey(f)
                except ImageReadError as e:
                    self.get_logger().warn(f"skipped: {e}")
                    continue
                msg = Image(header=self._header(), **grey_to_image_fields(img))
            self._publish(msg, f.name)

    def _replay_bag(self) -> None:
        rate = float(self.p("rate"))
        timed = self.mode == "timed"
        with_poses = bool(self.pose_topic)
        lead = int(float(self.p("pose_lead")) * 1e9)
        t_start, ts0 = time.monotonic(), None
        offset: int | None = None  # recorded stamp -> published stamp (arm sessions; one per pass)
        items = iter(self._bag_items())
        ahead: deque[Any] = deque()  # read ahead for the poses that must precede an image
        k = -1
        while not self.done.is_set():
            item = ahead.popleft() if ahead else next(items, None)
            if item is None:
                return
            if with_poses and offset is None:
                offset = self.get_clock().now().nanoseconds - _recorded_stamp(item)
            if isinstance(item, BagPose):
                if timed and rate <= 0:
                    ts0 = item.timestamp_ns if ts0 is None else ts0
                    self._sleep_until(t_start + (item.timestamp_ns - ts0) * 1e-9)
                self._publish_pose(item, offset or 0)
                continue
            k += 1
            if timed and rate > 0:
                self._sleep_until(t_start + k / rate)
            elif timed:
                ts0 = item.timestamp_ns if ts0 is None else ts0
                self._sleep_until(t_start + (item.timestamp_ns - ts0) * 1e-9)
            if with_poses:  # every pose up to the image's stamp + pose_lead goes first
                limit = _recorded_stamp(item) + lead
                while not ahead or _recorded_stamp(ahead[-1]) <= limit:
                    nxt = next(items, None)
                    if nxt is None:
                        break
                    ahead.append(nxt)
                early = [x for x in ahead if isinstance(x, BagPose) and _recorded_stamp(x) <= limit]
                for x in early:
                    ahead.remove(x)
                    self._publish_pose(x, offset or 0)
            if with_poses:
                header = self._header(item.frame_id)
                stamp = _recorded_stamp(item) + (offset or 0)
                header.stamp.sec, header.stamp.nanosec = stamp // 10**9, stamp % 10**9
            else:
                header = self._header(item.frame_id)
            msg: Image | CompressedImage
            if item.msgtype == COMPRESSED_TYPE:
                if self.pub_compressed is None:
                    raise ReplayError(f"bag message {k} is a CompressedImage among Images; give bag_topic")
                msg = CompressedImage(header=header, format=item.fields["format"])
                msg.data = item.fields["data"]
            else:
                if self.pub_raw is None:
                    raise ReplayError(f"bag message {k} is an Image among CompressedImages; give bag_topic")
                f = item.fields
                msg = Image(header=header, height=f["height"], width=f["width"], encoding=f["encoding"],
                            is_bigendian=f["is_bigendian"], step=f["step"])
                msg.data = f["data"]
            self._publish(msg, f"bag message {k}")

    def _publish_pose(self, item: BagPose, offset: int) -> None:
        from geometry_msgs.msg import PoseStamped

        stamp = item.stamp_ns + offset
        msg = self.pose_msg_type()
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp // 10**9, stamp % 10**9
        msg.header.frame_id = item.frame_id
        tx, ty, tz = item.translation
        qx, qy, qz, qw = item.rotation
        if isinstance(msg, PoseStamped):
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = tx, ty, tz
            o = msg.pose.orientation
        else:
            msg.child_frame_id = item.child_frame_id
            tr = msg.transform.translation
            tr.x, tr.y, tr.z = tx, ty, tz
            o = msg.transform.rotation
        o.x, o.y, o.z, o.w = qx, qy, qz, qw
        self.pub_pose.publish(msg)
        self.poses_published += 1

    def stop(self) -> None:
        self.done.set()
        self._thread.join(timeout=5.0)


def _recorded_stamp(item: BagImage | BagPose) -> int:
    """The header stamp of a bag message, its recording time if the header has none."""
    return item.stamp_ns or item.timestamp_ns


def output_topic(topic: str, compressed: bool) -> tuple[str, str]:
    """The topic frames go to, and a warning if the name looks wrong for them: compressed frames
    go to ``<topic>/compressed``, or to ``topic`` itself if it already ends in ``/compressed``
    (never ``.../compressed/compressed``); raw frames go to ``topic``."""
    topic = topic.rstrip("/") or topic
    ends_compressed = topic == "compressed" or topic.endswith("/compressed")
    if compressed:
        return (topic if ends_compressed else f"{topic}/compressed"), ""
    if ends_compressed:
        return topic, (f"topic {topic!r} ends in /compressed but the frames are raw sensor_msgs/Image "
                       "(transport raw): publishing them there as given; compressed-image subscribers "
                       "of that topic will not match")
    return topic, ""


def main(args: list[str] | None = None) -> int:
    from .spin import run_node

    nodes: list[ReplayNode] = []

    def make_node() -> ReplayNode:
        nodes.append(ReplayNode())
        return nodes[-1]

    code = run_node(make_node, (PascalCalibError,), "image_replay", SingleThreadedExecutor, args)
    return 1 if code == 0 and nodes and nodes[0].failed else code


if __name__ == "__main__":
    raise SystemExit(main())
