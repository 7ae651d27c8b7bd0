"""sensor_msgs/Image and CompressedImage <-> numpy, without cv_bridge and without rclpy.

Works on any object with the message's fields (rclpy messages, rosbags dataclasses), so it is
testable without ROS. Grey output: mono8 / mono16 pass through, colour is converted with
OpenCV, Bayer patterns are demosaiced; ``step`` is honoured (row padding). Anything else raises
:class:`ImageConversionError` with the reason.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from ..errors import PascalCalibError

MAX_PIXELS = 100_000_000  # refuse absurd sizes before allocating

_BAYER_TO_GREY = {
    "bayer_rggb8": cv2.COLOR_BayerRGGB2GRAY,
    "bayer_bggr8": cv2.COLOR_BayerBGGR2GRAY,
    "bayer_gbrg8": cv2.COLOR_BayerGBRG2GRAY,
    "bayer_grbg8": cv2.COLOR_BayerGRBG2GRAY,
    "bayer_rggb16": cv2.COLOR_BayerRGGB2GRAY,
    "bayer_bggr16": cv2.COLOR_BayerBGGR2GRAY,
    "bayer_gbrg16": cv2.COLOR_BayerGBRG2GRAY,
    "bayer_grbg16": cv2.COLOR_BayerGRBG2GRAY,
}
# encoding -> (channels, dtype, conversion to grey or None)
_ENCODINGS: dict[str, tuple[int, type, int | None]] = {
    "mono8": (1, np.uint8, None),
    "8uc1": (1, np.uint8, None),
    "mono16": (1, np.uint16, None),
    "16uc1": (1, np.uint16, None),
    "rgb8": (3, np.uint8, cv2.COLOR_RGB2GRAY),
    "bgr8": (3, np.uint8, cv2.COLOR_BGR2GRAY),
    "rgba8": (4, np.uint8, cv2.COLOR_RGBA2GRAY),
    "bgra8": (4, np.uint8, cv2.COLOR_BGRA2GRAY),
    **{k: (1, np.uint16 if k.endswith("16") else np.uint8, v) for k, v in _BAYER_TO_GREY.items()},
}
SUPPORTED_ENCODINGS = tuple(sorted(_ENCODINGS))


class ImageConversionError(PascalCalibError):
    """The message cannot be turned into an image; the message says why."""


def image_to_grey(msg: Any) -> np.ndarray:
    """sensor_msgs/Image -> grey uint8 or uint16 array (H, W)."""
    enc = str(msg.encoding).lower()
    if enc not in _ENCODINGS:
        raise ImageConversionError(
            f"unsupported encoding {msg.encoding!r} (supported: {', '.join(SUPPORTED_ENCODINGS)})")
    ch, dtype, code = _ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0:
        raise ImageConversionError(f"empty image {w}x{h}")
    if h * w > MAX_PIXELS:
        raise ImageConversionError(f"image {w}x{h} is larger than {MAX_PIXELS} pixels")
    itemsize = np.dtype(dtype).itemsize
    row = w * ch * itemsize
    if step < row:
        raise ImageConversionError(f"step {step} is smaller than width x channels x bytes = {row} for {enc}")
    buf = np.frombuffer(msg.data, dtype=np.uint8)  # no copy from array.array / bytes
    if buf.size < step * (h - 1) + row:
        raise ImageConversionError(f"data has {buf.size} bytes; {w}x{h} {enc} with step {step} needs "
                                   f"{step * (h - 1) + row}")
    rows = np.lib.stride_tricks.as_strided(buf, shape=(h, row), strides=(step, 1))
    big_endian = bool(getattr(msg, "is_bigendian", 0))
    arr = np.ascontiguousarray(rows).view(np.dtype(dtype).newbyteorder(">" if big_endian else "<"))
    arr = arr.astype(dtype, copy=False).reshape(h, w, ch) if ch > 1 else arr.astype(dtype, copy=False).reshape(h, w)
    if code is None:
        return arr
    return np.asarray(cv2.cvtColor(arr, code))


def compressed_to_grey(msg: Any) -> np.ndarray:
    """sensor_msgs/CompressedImage (jpeg/png, incl. image_transport's "mono8; jpeg ...") -> grey."""
    buf = np.frombuffer(msg.data, dtype=np.uint8)
    if buf.size == 0:
        raise ImageConversionError("compressed image has no data")
    img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageConversionError(f"cannot decode compressed image (format {msg.format!r}, {buf.size} bytes): "
                                   "corrupt or truncated")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    return np.asarray(img)


def grey_to_image_fields(img: np.ndarray) -> dict[str, Any]:
    """Fields of a sensor_msgs/Image for a grey (mono8/mono16) or BGR (bgr8) array."""
    if img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8:
        enc, ch = "bgr8", 3
    elif img.ndim == 2 and img.dtype == np.uint8:
        enc, ch = "mono8", 1
    elif img.ndim == 2 and img.dtype == np.uint16:
        enc, ch = "mono16", 1
    else:
        raise ImageConversionError(f"cannot publish an array of shape {img.shape} and type {img.dtype}")
    h, w = img.shape[:2]
    return {"height": h, "width": w, "encoding": enc, "is_bigendian": 0,
            "step": w * ch * img.dtype.itemsize, "data": np.ascontiguousarray(img).tobytes()}
