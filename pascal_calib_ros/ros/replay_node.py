"""ROS 2 image replay node ``image_replay`` (executable ``replay_node``).

Publishes a folder or glob of image files, or the images of a rosbag2 bag (sqlite3 or mcap), as
sensor_msgs/Image on ``topic`` or sensor_msgs/CompressedImage on ``<topic>/compressed``, with
headers stamped at publication time. For recording once and calibrating later, see
``pascal-calib bag`` (a folder of images into a bag).
"""

from __future__ import annotations

import glob
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Header

from ..io.bags import COMPRESSED_TYPE, BagError, read_images
from ..io.image_msgs import grey_to_image_fields
from ..io.images import IMAGE_SUFFIXES, ImageReadError, read_grey

PARAMS: tuple[tuple[str, Any, str], ...] = (
    ("source", "", "folder, glob of image files, or rosbag2 bag folder/file"),
    ("bag_topic", "", "image topic to replay from a bag (needed when it has several)"),
    ("topic", "image", "output topic (compressed images go to <topic>/compressed)"),
    ("rate", 2.0, "messages per second; 0 = recorded timing (bags only)"),
    ("loop", False, "start again at the end"),
    ("frame_id", "", "header frame_id; empty: the bag's, else 'camera'"),
    ("start_delay", 0.0, "seconds to wait before the first message"),
    ("wait_for_subscribers", 0, "wait (up to 30 s) until this many subscribers are matched, then 0.5 s"),
    ("exit_when_done", False, "shut down after the last message (ignored with loop)"),
    ("qos", "reliable", "reliable | best_effort"),
    ("transport", "raw", "folders: raw (decode to Image) | compressed (file bytes as CompressedImage)"),
)


class ReplayError(ValueError):
    pass


class ReplayNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("image_replay", **kwargs)
        for name, default, desc in PARAMS:
            d = ParameterDescriptor(description=desc, read_only=True)
            if name in ("rate", "start_delay"):
                d.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=1000.0, step=0.0)]
            self.declare_parameter(name, default, d)
        self.source = str(self.p("source"))
        if not self.source:
            raise ReplayError("parameter 'source' is empty: give a folder, a glob or a bag")
        if self.p("qos") not in ("reliable", "best_effort"):
            raise ReplayError(f"qos must be reliable or best_effort, got {self.p('qos')!r}")
        if self.p("transport") not in ("raw", "compressed"):
            raise ReplayError(f"transport must be raw or compressed, got {self.p('transport')!r}")
        self.is_bag = self._looks_like_bag(self.source)
        self.files: list[Path] = []
        if not self.is_bag:
            self.files = self._image_files(self.source)
            if float(self.p("rate")) <= 0:
                raise ReplayError("rate 0 (recorded timing) needs a bag; set rate > 0 for image files")
        else:
            next(iter(self._bag_items()), None)  # open early: a missing or corrupt bag fails at start
        qos = QoSProfile(depth=5, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE if self.p("qos") == "reliable"
                         else ReliabilityPolicy.BEST_EFFORT)
        topic = str(self.p("topic"))
        self.pub_raw = self.create_publisher(Image, topic, qos)
        self.pub_compressed = self.create_publisher(CompressedImage, f"{topic}/compressed", qos)
        self.published = 0
        self.done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="replay", daemon=True)
        self._thread.start()

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

    def _bag_items(self) -> Iterator[Any]:
        path = Path(self.source)
        if path.suffix in (".mcap", ".db3"):
            path = path.parent
        return read_images(path, str(self.p("bag_topic")))

    def _header(self, frame_id: str = "") -> Header:
        fid = str(self.p("frame_id")) or frame_id or "camera"
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=fid)

    def _wait_for_subscribers(self) -> None:
        want = int(self.p("wait_for_subscribers"))
        deadline = time.monotonic() + 30.0
        while want > 0 and time.monotonic() < deadline and not self.done.is_set():
            n = self.pub_raw.get_subscription_count() + self.pub_compressed.get_subscription_count()
            if n >= want:
                # the publisher sees the subscriber before the subscriber has matched the
                # publisher; messages sent in between can be lost: let discovery settle
                time.sleep(0.5)
                return
            time.sleep(0.05)

    def _run(self) -> None:
        try:
            time.sleep(float(self.p("start_delay")))
            self._wait_for_subscribers()
            while not self.done.is_set():
                if self.is_bag:
                    self._replay_bag()
                else:
                    self._replay_files()
                if not self.p("loop"):
                    break
            self.get_logger().info(f"replay finished: {self.published} message(s)")
        except (BagError, ReplayError) as e:
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
        period = 1.0 / float(self.p("rate"))
        t_next = time.monotonic()
        for f in self.files:
            if self.done.is_set():
                return
            self._sleep_until(t_next)
            t_next += period
            if self.p("transport") == "compressed":
                msg = CompressedImage(header=self._header(), format="png" if f.suffix.lower() == ".png" else "jpeg")
                msg.data = f.read_bytes()
                self.pub_compressed.publish(msg)
            else:
                try:
                    img = read_grey(f)
                except ImageReadError as e:
                    self.get_logger().warn(f"skipped: {e}")
                    continue
                self.pub_raw.publish(Image(header=self._header(), **grey_to_image_fields(img)))
            self.published += 1

    def _replay_bag(self) -> None:
        rate = float(self.p("rate"))
        t_start, ts0 = time.monotonic(), None
        for k, item in enumerate(self._bag_items()):
            if self.done.is_set():
                return
            if rate > 0:
                self._sleep_until(t_start + k / rate)
            else:
                ts0 = item.timestamp_ns if ts0 is None else ts0
                self._sleep_until(t_start + (item.timestamp_ns - ts0) * 1e-9)
            header = self._header(item.frame_id)
            if item.msgtype == COMPRESSED_TYPE:
                msg = CompressedImage(header=header, format=item.fields["format"])
                msg.data = item.fields["data"]
                self.pub_compressed.publish(msg)
            else:
                f = item.fields
                img_msg = Image(header=header, height=f["height"], width=f["width"], encoding=f["encoding"],
                                is_bigendian=f["is_bigendian"], step=f["step"])
                img_msg.data = f["data"]
                self.pub_raw.publish(img_msg)
            self.published += 1

    def stop(self) -> None:
        self.done.set()
        self._thread.join(timeout=5.0)


def main(args: list[str] | None = None) -> int:
    from .spin import run_node

    return run_node(ReplayNode, (ReplayError, BagError, ImageReadError), "image_replay", SingleThreadedExecutor, args)


if __name__ == "__main__":
    raise SystemExit(main())
