"""rosbag2 files (sqlite3 or mcap) read and written with the pure-Python ``rosbags`` library.

Images are yielded as plain field dictionaries so that the ROS layer builds its own messages.
Robot arm sessions: :func:`write_arm_bag` writes images and the robot's tool poses
(geometry_msgs/PoseStamped or TransformStamped) as a driver would publish them while the arm
rests at each pose; :func:`read_session` yields both in recorded order.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..errors import PascalCalibError
from ..geometry import Transform
from .images import read_grey

IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TRANSFORM_TYPE = "geometry_msgs/msg/TransformStamped"
POSE_TYPES = (POSE_TYPE, TRANSFORM_TYPE)


class BagError(PascalCalibError):
    """The bag is missing, corrupt, or has no suitable topic."""


@dataclass
class BagImage:
    timestamp_ns: int
    msgtype: str  # IMAGE_TYPE or COMPRESSED_TYPE
    fields: dict[str, Any]  # Image: height width encoding is_bigendian step data; Compressed: format data
    frame_id: str
    stamp_ns: int = 0  # the header stamp


@dataclass
class BagPose:
    """A robot pose message of a bag: the tool (child) in the base (frame_id) at stamp_ns."""

    timestamp_ns: int  # when it was recorded
    msgtype: str  # POSE_TYPE or TRANSFORM_TYPE
    stamp_ns: int  # the header stamp
    frame_id: str
    child_frame_id: str  # TransformStamped only ("" for PoseStamped)
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]  # x, y, z, w


def make_typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def image_topics(path: str | Path) -> dict[str, str]:
    """Image and CompressedImage topics of a bag -> message type."""
    from rosbags.rosbag2 import Reader

    try:
        with Reader(Path(path)) as reader:
            return {c.topic: c.msgtype for c in reader.connections if c.msgtype in (IMAGE_TYPE, COMPRESSED_TYPE)}
    except Exception as e:  # rosbags raises several types for unreadable bags
        raise BagError(f"cannot open bag {path}: {e}") from None


def read_images(path: str | Path, topic: str = "") -> Iterator[BagImage]:
    """Yield the images of ``topic`` (or of the only image topic) in recorded order. A corrupt
    message is skipped with a :class:`BagError` only if nothing can be read at all."""
    from rosbags.rosbag2 import Reader

    p = Path(path)
    if not p.exists():
        raise BagError(f"bag not found: {p}")
    topics = image_topics(p)
    if not topics:
        raise BagError(f"bag {p} has no sensor_msgs/Image or CompressedImage topic")
    if topic:
        if topic not in topics:
            raise BagError(f"bag {p} has no image topic {topic!r}; it has {', '.join(sorted(topics))}")
    elif len(topics) > 1:
        raise BagError(f"bag {p} has several image topics ({', '.join(sorted(topics))}); set bag_topic")
    else:
        topic = next(iter(topics))
    store = make_typestore()
    try:
        with Reader(p) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            for conn, ts, raw in reader.messages(connections=conns):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                yield bag_image(msg, conn.msgtype, ts)
    except BagError:
        raise
    except Exception as e:
        raise BagError(f"bag {p} is corrupt or truncated: {type(e).__name__}: {e}") from None


def bag_image(msg: Any, msgtype: str, ts: int) -> BagImage:
    """An Image or CompressedImage message of a bag as a BagImage (fields as the ROS message)."""
    if msgtype == IMAGE_TYPE:
        fields = {"height": msg.height, "width": msg.width, "encoding": msg.encoding,
                  "is_bigendian": msg.is_bigendian, "step": msg.step, "data": bytes(msg.data)}
    else:
        fields = {"format": msg.format, "data": bytes(msg.data)}
    return BagImage(int(ts), msgtype, fields, str(msg.header.frame_id), _stamp_ns(msg.header))


def write_image_bag(out: str | Path, images: list[Path], topic: str = "/image", storage: str = "sqlite3",
                    compressed: bool = False, rate: float = 2.0, frame_id: str = "camera") -> Path:
    """Write image files into a new rosbag2 bag as sensor_msgs/Image (mono8/mono16) or
    CompressedImage (PNG/JPEG bytes as they are), ``rate`` messages per second."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys.stores.ros2_jazzy import (
        builtin_interfaces__msg__Time as Time,
    )
    from rosbags.typesys.stores.ros2_jazzy import (
        sensor_msgs__msg__CompressedImage as CompressedImage,
    )
    from rosbags.typesys.stores.ros2_jazzy import (
        sensor_msgs__msg__Image as Image,
    )
    from rosbags.typesys.stores.ros2_jazzy import (
        std_msgs__msg__Header as Header,
    )

    if storage not in ("sqlite3", "mcap"):
        raise BagError(f"storage must be sqlite3 or mcap, got {storage!r}")
    if rate <= 0:
        raise BagError("rate must be positive")
    out_p = Path(out)
    if out_p.exists():
        raise BagError(f"{out_p} exists; rosbag2 writes a new folder")
    store = make_typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    t0 = 1_700_000_000 * 10**9
    with Writer(out_p, version=9, storage_plugin=plugin) as writer:
        msgtype = COMPRESSED_TYPE if compressed else IMAGE_TYPE
        conn = writer.add_connection(topic, msgtype, typestore=store)
        for k, path in enumerate(images):
            ts = t0 + int(k * 1e9 / rate)
            header = Header(stamp=Time(sec=ts // 10**9, nanosec=ts % 10**9), frame_id=frame_id)
            if compressed:
                data = path.read_bytes()
                fmt = "png" if path.suffix.lower() == ".png" else "jpeg"
                if cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) is None:
                    raise BagError(f"{path}: not a readable image")
                msg: Any = CompressedImage(header=header, format=fmt, data=np.frombuffer(data, np.uint8))
            else:
                img = read_grey(path)
                enc = "mono16" if img.dtype == np.uint16 else "mono8"
                msg = Image(header=header, height=img.shape[0], width=img.shape[1], encoding=enc, is_bigendian=0,
                            step=img.shape[1] * img.dtype.itemsize,
                            data=np.frombuffer(np.ascontiguousarray(img).tobytes(), np.uint8))
            writer.write(conn, ts, store.serialize_cdr(msg, msgtype))
    return out_p


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 10**9 + int(header.stamp.nanosec)


def pose_topics(path: str | Path) -> dict[str, str]:
    """PoseStamped and TransformStamped topics of a bag -> message type."""
    from rosbags.rosbag2 import Reader

    try:
        with Reader(Path(path)) as reader:
            return {c.topic: c.msgtype for c in reader.connections if c.msgtype in POSE_TYPES}
    except Exception as e:
        raise BagError(f"cannot open bag {path}: {e}") from None


def read_session(path: str | Path, image_topic: str = "", pose_topic: str = "") -> Iterator[BagImage | BagPose]:
    """The images of ``image_topic`` (or the only image topic) and the robot poses of
    ``pose_topic`` (PoseStamped or TransformStamped) in recorded order; only images without
    ``pose_topic``."""
    from rosbags.rosbag2 import Reader

    p = Path(path)
    if not pose_topic:
        yield from read_images(p, image_topic)
        return
    if not p.exists():
        raise BagError(f"bag not found: {p}")
    images = image_topics(p)
    poses = pose_topics(p)
    if pose_topic not in poses:
        with Reader(p) as reader:
            other = {c.topic: c.msgtype for c in reader.connections}
        if pose_topic in other:
            raise BagError(f"bag {p}: topic {pose_topic!r} is a {other[pose_topic]}, not a "
                           "geometry_msgs/PoseStamped or TransformStamped")
        raise BagError(f"bag {p} has no pose topic {pose_topic!r}; pose topics: {', '.join(sorted(poses)) or 'none'}")
    if image_topic:
        if image_topic not in images:
            raise BagError(f"bag {p} has no image topic {image_topic!r}; it has {', '.join(sorted(images))}")
    elif len(images) != 1:
        raise BagError(f"bag {p} has {len(images)} image topics ({', '.join(sorted(images))}); set bag_topic")
    else:
        image_topic = next(iter(images))
    store = make_typestore()
    try:
        with Reader(p) as reader:
            conns = [c for c in reader.connections if c.topic in (image_topic, pose_topic)]
            for conn, ts, raw in reader.messages(connections=conns):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                if conn.topic == pose_topic:
                    if conn.msgtype == POSE_TYPE:
                        t, q, child = msg.pose.position, msg.pose.orientation, ""
                    else:
                        t, q, child = msg.transform.translation, msg.transform.rotation, str(msg.child_frame_id)
                    yield BagPose(int(ts), conn.msgtype, _stamp_ns(msg.header), str(msg.header.frame_id), child,
                                  (float(t.x), float(t.y), float(t.z)),
                                  (float(q.x), float(q.y), float(q.z), float(q.w)))
                else:
                    yield bag_image(msg, conn.msgtype, ts)
    except BagError:
        raise
    except Exception as e:
        raise BagError(f"bag {p} is corrupt or truncated: {type(e).__name__}: {e}") from None


def arm_schedule(n_images: int, rate: float, hold: float, pose_rate: float, t0_ns: int = 1_700_000_000 * 10**9
                 ) -> list[tuple[int, int, str]]:
    """The messages of an arm session bag in recorded order: (stamp ns, pose index, "pose" |
    "image"). The arm rests ``hold`` seconds at each pose; the camera gives max(1, round(hold *
    rate)) frames of it at ``rate`` Hz; the driver publishes the pose at ``pose_rate`` Hz over the
    hold and at every frame's stamp (frame and pose stamps equal). At equal stamps the pose
    comes first."""
    if rate <= 0 or pose_rate <= 0 or hold <= 0:
        raise BagError("rate, pose rate and hold must be positive")
    frames = max(1, round(hold * rate))
    span = max(hold, frames / rate)
    out: list[tuple[int, int, str]] = []
    for k in range(n_images):
        start = t0_ns + round(k * span * 1e9)
        img = {start + round(j * 1e9 / rate) for j in range(frames)}
        pose = {start + round(j * 1e9 / pose_rate) for j in range(max(1, round(span * pose_rate)))} | img
        out += [(t, k, "pose") for t in pose] + [(t, k, "image") for t in img]
    return sorted(out, key=lambda m: (m[0], m[2] == "image"))


class ArmMessages:
    """The messages of an arm session bag: each image file read once (sent at every frame of its pose)
    and the tool pose as PoseStamped (``pose_type`` "pose": header.frame_id = the base) or
    TransformStamped ("transform": child_frame_id = the tool)."""

    def __init__(self, images: list[Path], compressed: bool, frame_id: str, base: str, tool: str, pose_type: str):
        from rosbags.typesys.stores.ros2_jazzy import builtin_interfaces__msg__Time as Time
        from rosbags.typesys.stores.ros2_jazzy import std_msgs__msg__Header as Header

        self.Time, self.Header = Time, Header
        self.images, self.compressed, self.frame_id = images, compressed, frame_id
        self.base, self.tool, self.pose_type = base, tool, pose_type
        self.payload: dict[int, tuple[str, Any]] = {}

    def stamp(self, ts: int) -> Any:
        return self.Time(sec=ts // 10**9, nanosec=ts % 10**9)

    def image(self, k: int, ts: int) -> Any:
        from rosbags.typesys.stores.ros2_jazzy import sensor_msgs__msg__CompressedImage as CompressedImage
        from rosbags.typesys.stores.ros2_jazzy import sensor_msgs__msg__Image as Image

        header = self.Header(stamp=self.stamp(ts), frame_id=self.frame_id)
        path = self.images[k]
        if k not in self.payload:
            if self.compressed:
                data = path.read_bytes()
                if cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) is None:
                    raise BagError(f"{path}: not a readable image")
                self.payload[k] = ("png" if path.suffix.lower() == ".png" else "jpeg", np.frombuffer(data, np.uint8))
            else:
                self.payload[k] = ("", read_grey(path))
        fmt, data = self.payload[k]
        if self.compressed:
            return CompressedImage(header=header, format=fmt, data=data)
        enc = "mono16" if data.dtype == np.uint16 else "mono8"
        return Image(header=header, height=data.shape[0], width=data.shape[1], encoding=enc, is_bigendian=0,
                     step=data.shape[1] * data.dtype.itemsize,
                     data=np.frombuffer(np.ascontiguousarray(data).tobytes(), np.uint8))

    def pose(self, T: Transform, ts: int) -> Any:
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Point as Point
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Pose as Pose
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__PoseStamped as PoseStamped
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Quaternion as Quaternion
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Transform as TransformMsg
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__TransformStamped as TransformStamped
        from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Vector3 as Vector3

        t, q = T.translation, T.quat
        header = self.Header(stamp=self.stamp(ts), frame_id=self.base)
        rotation = Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))
        if self.pose_type == "pose":
            return PoseStamped(header=header, pose=Pose(position=Point(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                                                        orientation=rotation))
        return TransformStamped(header=header, child_frame_id=self.tool, transform=TransformMsg(
            translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])), rotation=rotation))


def _arm_poses(images: list[Path], poses_yaml: str | Path) -> tuple[str, str, dict[str, Transform]]:
    """(base frame, tool frame, poses by file name) of POSES.yaml, every image having one."""
    from .hand_eye_yaml import PosesYamlError, read_poses_yaml

    try:
        base, tool, table = read_poses_yaml(poses_yaml)
    except PosesYamlError as e:
        raise BagError(str(e)) from None
    missing = [p.name for p in images if p.name not in table]
    if missing:
        raise BagError(f"{poses_yaml} has no pose for {', '.join(missing[:5])}"
                       + (f" and {len(missing) - 5} more" if len(missing) > 5 else ""))
    return base, tool, table


def write_arm_bag(out: str | Path, images: list[Path], poses_yaml: str | Path, *, topic: str = "/image",
                  pose_topic: str = "/tool_pose", storage: str = "sqlite3", compressed: bool = False,
                  rate: float = 5.0, hold: float = 1.0, pose_rate: float = 20.0, frame_id: str = "camera",
                  pose_type: str = "pose") -> Path:
    """A recorded robot-arm session: every image (matched by file name to an entry of
    POSES.yaml, :func:`~.hand_eye_yaml.read_poses_yaml`) shown while the arm rests at its pose
    (:func:`arm_schedule`), with the tool pose in the base frame as geometry_msgs/PoseStamped
    (``pose_type`` "pose": header.frame_id = the base) or TransformStamped ("transform":
    child_frame_id = the tool) on ``pose_topic``."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    if storage not in ("sqlite3", "mcap"):
        raise BagError(f"storage must be sqlite3 or mcap, got {storage!r}")
    if pose_type not in ("pose", "transform"):
        raise BagError(f"pose type must be pose or transform, got {pose_type!r}")
    base, tool, table = _arm_poses(images, poses_yaml)
    out_p = Path(out)
    if out_p.exists():
        raise BagError(f"{out_p} exists; rosbag2 writes a new folder")
    store = make_typestore()
    img_type = COMPRESSED_TYPE if compressed else IMAGE_TYPE
    msg_pose_type = POSE_TYPE if pose_type == "pose" else TRANSFORM_TYPE
    msgs = ArmMessages(images, compressed, frame_id, base, tool, pose_type)
    with Writer(out_p, version=9, storage_plugin=StoragePlugin.MCAP if storage == "mcap" else
                StoragePlugin.SQLITE3) as writer:
        img_conn = writer.add_connection(topic, img_type, typestore=store)
        pose_conn = writer.add_connection(pose_topic, msg_pose_type, typestore=store)
        for ts, k, kind in arm_schedule(len(images), rate, hold, pose_rate):
            if kind == "image":
                writer.write(img_conn, ts, store.serialize_cdr(msgs.image(k, ts), img_type))
            else:
                writer.write(pose_conn, ts, store.serialize_cdr(msgs.pose(table[images[k].name], ts), msg_pose_type))
    return out_p
