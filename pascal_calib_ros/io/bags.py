"""rosbag2 files (sqlite3 or mcap) read and written with the pure-Python ``rosbags`` library.

Images are yielded as plain field dictionaries so that the ROS layer builds its own messages.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .images import read_grey

IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"


class BagError(ValueError):
    """The bag is missing, corrupt, or has no suitable topic."""


@dataclass
class BagImage:
    timestamp_ns: int
    msgtype: str  # IMAGE_TYPE or COMPRESSED_TYPE
    fields: dict[str, Any]  # Image: height width encoding is_bigendian step data; Compressed: format data
    frame_id: str


def _typestore() -> Any:
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
    store = _typestore()
    try:
        with Reader(p) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            for conn, ts, raw in reader.messages(connections=conns):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                if conn.msgtype == IMAGE_TYPE:
                    fields = {"height": msg.height, "width": msg.width, "encoding": msg.encoding,
                              "is_bigendian": msg.is_bigendian, "step": msg.step, "data": bytes(msg.data)}
                else:
                    fields = {"format": msg.format, "data": bytes(msg.data)}
                yield BagImage(int(ts), conn.msgtype, fields, str(msg.header.frame_id))
    except BagError:
        raise
    except Exception as e:
        raise BagError(f"bag {p} is corrupt or truncated: {type(e).__name__}: {e}") from None


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
    store = _typestore()
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
