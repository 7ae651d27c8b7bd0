"""Test-side encoder: a grey image as the fields of a sensor_msgs/Image in any supported encoding
(the inverse of ``io.image_msgs.image_to_grey`` for grey content; not part of the package)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

# encoding -> (channels, 16-bit); colour channels all carry the grey value (alpha: 255 / 65535)
_INTERLEAVED = {"mono8": (1, False), "8uc1": (1, False), "mono16": (1, True), "16uc1": (1, True),
                "rgb8": (3, False), "bgr8": (3, False), "rgba8": (4, False), "bgra8": (4, False),
                "rgb16": (3, True), "bgr16": (3, True), "rgba16": (4, True), "bgra16": (4, True)}
YUV422 = {"uyvy": 1, "yuv422": 1, "yuyv": 0, "yuv422_yuy2": 0}  # byte offset of the first Y sample
YUV420 = ("nv12", "nv21")


def pack_rows(raw: np.ndarray, pad: int) -> tuple[int, bytes]:
    """Rows of bytes (R, B) with ``pad`` bytes of junk after each: (step, data)."""
    step = raw.shape[1] + pad
    buf = np.full((raw.shape[0], step), 0xA5, np.uint8)
    buf[:, : raw.shape[1]] = raw
    return step, buf.tobytes()


def encode_grey(grey: np.ndarray, enc: str, pad: int = 0, big: bool = False, seed: int = 0) -> SimpleNamespace:
    """Image message fields showing ``grey`` (uint8; 16-bit encodings carry grey * 257) in
    ``enc``; YUV chroma is random (it must not reach the grey image)."""
    h, w = grey.shape
    rng = np.random.default_rng(seed)
    if enc in YUV422:
        raw = rng.integers(0, 256, (h, 2 * w), dtype=np.uint8)
        raw[:, YUV422[enc]::2] = grey
    elif enc in YUV420:
        raw = np.concatenate([grey, rng.integers(0, 256, (h // 2, w), dtype=np.uint8)])
    else:
        ch, deep = _INTERLEAVED[enc]
        px = grey.astype(np.uint16) * 257 if deep else grey
        full = np.iinfo(px.dtype).max
        arr = np.dstack([px] * min(ch, 3) + [np.full_like(px, full)] * (ch - 3)) if ch > 1 else px
        arr = arr.reshape(h, -1)
        if deep:
            arr = arr.astype(arr.dtype.newbyteorder(">" if big else "<"))
        raw = np.ascontiguousarray(arr).view(np.uint8).reshape(h, -1)
    step, data = pack_rows(raw, pad)
    return SimpleNamespace(height=h, width=w, encoding=enc, step=step, is_bigendian=int(big), data=data)
