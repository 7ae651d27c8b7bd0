"""sensor_msgs/Image and CompressedImage <-> numpy, without cv_bridge and without rclpy.

Works on any object with the message's fields (rclpy messages, rosbags dataclasses), so it is
testable without ROS. Grey output: mono8 / mono16 pass through; 8- and 16-bit colour is converted
with OpenCV (16-bit stays 16-bit, like mono16); Bayer patterns are demosaiced; the YUV encodings
give their luma samples as they are (no colour conversion: Y is the grey image): packed 4:2:2
``uyvy`` (= ``yuv422``) and ``yuyv`` (= ``yuv422_yuy2``), semi-planar 4:2:0 ``nv12`` and ``nv21``
(the Y plane's ``height`` rows, then ``height / 2`` rows of interleaved chroma, one ``step`` for
both planes). ``step`` is honoured (row padding) and ``is_bigendian`` for 16-bit data. Anything
else raises :class:`ImageConversionError` with the reason; :data:`SUPPORTED_ENCODINGS` is the one
list of what is accepted (errors and :func:`supported_encodings_text` quote it).

Encoding names and layouts: ROS 2 ``sensor_msgs/image_encodings.hpp`` (Jazzy) and the Linux V4L2
pixel-format documentation (packed YUV: UYVY, YUYV; planar YUV: NV12, NV21).
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
# encoding -> (channels, dtype, conversion to grey or None): one or more samples per pixel
_ENCODINGS: dict[str, tuple[int, type, int | None]] = {
    "mono8": (1, np.uint8, None),
    "8uc1": (1, np.uint8, None),
    "mono16": (1, np.uint16, None),
    "16uc1": (1, np.uint16, None),
    "rgb8": (3, np.uint8, cv2.COLOR_RGB2GRAY),
    "bgr8": (3, np.uint8, cv2.COLOR_BGR2GRAY),
    "rgba8": (4, np.uint8, cv2.COLOR_RGBA2GRAY),
    "bgra8": (4, np.uint8, cv2.COLOR_BGRA2GRAY),
    "rgb16": (3, np.uint16, cv2.COLOR_RGB2GRAY),
    "bgr16": (3, np.uint16, cv2.COLOR_BGR2GRAY),
    "rgba16": (4, np.uint16, cv2.COLOR_RGBA2GRAY),
    "bgra16": (4, np.uint16, cv2.COLOR_BGRA2GRAY),
    **{k: (1, np.uint16 if k.endswith("16") else np.uint8, v) for k, v in _BAYER_TO_GREY.items()},
}
# packed YUV 4:2:2, two bytes per pixel (a pair of pixels shares U and V): the byte offset of the
# first Y sample (UYVY: U0 Y0 V0 Y1; YUYV: Y0 U0 Y1 V0)
_YUV422_Y_OFFSET = {"uyvy": 1, "yuv422": 1, "yuyv": 0, "yuv422_yuy2": 0}
# semi-planar YUV 4:2:0: a Y plane of height rows, then height / 2 rows of interleaved chroma
_YUV420_SEMIPLANAR = ("nv12", "nv21")
SUPPORTED_ENCODINGS = tuple(sorted([*_ENCODINGS, *_YUV422_Y_OFFSET, *_YUV420_SEMIPLANAR]))


def supported_encodings_text() -> str:
    """:data:`SUPPORTED_ENCODINGS` for a user: comma-separated, lower case as ROS spells them
    (OpenCV type names such as ``8UC1`` are matched case-insensitively)."""
    return ", ".join(SUPPORTED_ENCODINGS)


class ImageConversionError(PascalCalibError):
    """The message cannot be turned into an image; the message says why."""


def _rows(msg: Any, enc: str, row_bytes: int, n_rows: int) -> np.ndarray:
    """The first ``row_bytes`` bytes of each of ``n_rows`` rows of ``msg.data`` (``msg.step``
    bytes apart), as a (n_rows, row_bytes) uint8 view without a copy."""
    step = int(msg.step)
    if step < row_bytes:
        raise ImageConversionError(f"step {step} is smaller than the {row_bytes} bytes of a row of a "
                                   f"{msg.width}-pixel-wide {enc} image")
    buf = np.frombuffer(msg.data, dtype=np.uint8)  # no copy from array.array / bytes
    need = step * (n_rows - 1) + row_bytes
    if buf.size < need:
        raise ImageConversionError(f"data has {buf.size} bytes; {msg.width}x{msg.height} {enc} with step {step} "
                                   f"needs {need} ({n_rows} rows)")
    return np.lib.stride_tricks.as_strided(buf, shape=(n_rows, row_bytes), strides=(step, 1))


def image_to_grey(msg: Any) -> np.ndarray:
    """sensor_msgs/Image -> grey uint8 or uint16 array (H, W). YUV encodings give their Y samples."""
    enc = str(msg.encoding).lower()
    if enc not in SUPPORTED_ENCODINGS:
        raise ImageConversionError(f"unsupported encoding {msg.encoding!r} (supported: {supported_encodings_text()})")
    h, w = int(msg.height), int(msg.width)
    if h <= 0 or w <= 0:
        raise ImageConversionError(f"empty image {w}x{h}")
    if h * w > MAX_PIXELS:
        raise ImageConversionError(f"image {w}x{h} is larger than {MAX_PIXELS} pixels")
    if enc in _YUV422_Y_OFFSET:
        if w % 2:
            raise ImageConversionError(f"{enc} (YUV 4:2:2) needs an even width, got {w}: two pixels share "
                                       "one U and one V sample")
        off = _YUV422_Y_OFFSET[enc]
        return np.ascontiguousarray(_rows(msg, enc, 2 * w, h)[:, off::2])
    if enc in _YUV420_SEMIPLANAR:
        if w % 2 or h % 2:
            raise ImageConversionError(f"{enc} (YUV 4:2:0) needs an even width and height, got {w}x{h}: "
                                       "2x2 pixels share one U and one V sample")
        return np.ascontiguousarray(_rows(msg, enc, w, h + h // 2)[:h])
    ch, dtype, code = _ENCODINGS[enc]
    rows = _rows(msg, enc, w * ch * np.dtype(dtype).itemsize, h)
    big_endian = bool(getattr(msg, "is_bigendian", 0))
    arr = np.ascontiguousarray(rows).view(np.dtype(dtype).newbyteorder(">" if big_endian else "<"))
    arr = arr.astype(dtype, copy=False).reshape((h, w, ch) if ch > 1 else (h, w))
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
