"""rosbag2 files of a stereo pair: two image topics, read in recorded order and written from paired
image files (record once, calibrate later; the tests' stereo sessions).

A stereo driver records ``/left/image_raw`` and ``/right/image_raw`` (or their ``compressed``
variants); each frame's header stamp is its exposure time, equal for hardware-triggered cameras,
a few milliseconds apart otherwise (:func:`write_stereo_bag`'s ``right_delay``).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from .bags import COMPRESSED_TYPE, IMAGE_TYPE, ArmMessages, BagError, BagImage, bag_image, image_topics, make_typestore


def read_image_topics(path: str | Path, topics: tuple[str, str]) -> Iterator[tuple[int, BagImage]]:
    """(0 for ``topics[0]``, 1 for ``topics[1]``; the image) of both topics in recorded order; a
    :class:`~.bags.BagError` naming the bag's image topics when one is missing."""
    from rosbags.rosbag2 import Reader

    p = Path(path)
    if not p.exists():
        raise BagError(f"bag not found: {p}")
    have = image_topics(p)
    missing = [t for t in topics if t not in have]
    if missing:
        raise BagError(f"bag {p} has no image topic {', '.join(repr(t) for t in missing)}; it has "
                       f"{', '.join(sorted(have)) or 'none'}")
    if topics[0] == topics[1]:
        raise BagError(f"the left and the right image topic are both {topics[0]!r}")
    store = make_typestore()
    try:
        with Reader(p) as reader:
            conns = [c for c in reader.connections if c.topic in topics]
            for conn, ts, raw in reader.messages(connections=conns):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                yield topics.index(conn.topic), bag_image(msg, conn.msgtype, ts)
    except BagError:
        raise
    except Exception as e:
        raise BagError(f"bag {p} is corrupt or truncated: {type(e).__name__}: {e}") from None


def write_stereo_bag(out: str | Path, left: list[Path], right: list[Path], *,
                     topics: tuple[str, str] = ("/left/image_raw", "/right/image_raw"), storage: str = "sqlite3",
                     compressed: bool = False, rate: float = 2.0,
                     frame_ids: tuple[str, str] = ("left_camera_optical_frame", "right_camera_optical_frame"),
                     right_delay: float = 0.0) -> Path:
    """A recorded stereo session: shot k's left and right files (``left[k]``, ``right[k]``) as
    sensor_msgs/Image (mono8/mono16) or CompressedImage (the files' bytes) on ``topics`` at ``rate``
    shots per second, the right frame's stamp ``right_delay`` seconds after the left's (0:
    synchronised cameras)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    if len(left) != len(right):
        raise BagError(f"a stereo bag needs one right image per left image, got {len(left)} and {len(right)}")
    if storage not in ("sqlite3", "mcap"):
        raise BagError(f"storage must be sqlite3 or mcap, got {storage!r}")
    if rate <= 0:
        raise BagError("rate must be positive")
    if not 0 <= right_delay < 1.0 / rate:
        raise BagError(f"right_delay must be in [0, 1 / rate) s, got {right_delay}")
    out_p = Path(out)
    if out_p.exists():
        raise BagError(f"{out_p} exists; rosbag2 writes a new folder")
    store = make_typestore()
    msgtype = COMPRESSED_TYPE if compressed else IMAGE_TYPE
    cams = [ArmMessages(files, compressed, frame_id, "", "", "pose") for files, frame_id in
            zip((left, right), frame_ids, strict=True)]
    t0 = 1_700_000_000 * 10**9
    with Writer(out_p, version=9, storage_plugin=StoragePlugin.MCAP if storage == "mcap" else
                StoragePlugin.SQLITE3) as writer:
        conns: list[Any] = [writer.add_connection(t, msgtype, typestore=store) for t in topics]
        for k in range(len(left)):
            ts = t0 + round(k * 1e9 / rate)
            for c, delay in ((0, 0), (1, round(right_delay * 1e9))):
                writer.write(conns[c], ts + delay, store.serialize_cdr(cams[c].image(k, ts + delay), msgtype))
    return out_p
