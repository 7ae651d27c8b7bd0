"""Core results <-> ROS messages."""

from __future__ import annotations

from typing import Any

import numpy as np
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from ..calibrate.pipeline import CalibrationResult
from ..geometry.camera import rectified_projection
from ..io.image_msgs import grey_to_image_fields


def camera_info_msg(res: CalibrationResult, camera_name: str, header: Any) -> CameraInfo:
    """Monocular CameraInfo: K, D and ``distortion_model`` of the result's lens model
    (plumb_bob, rational_polynomial, equidistant), R = identity, P from
    :func:`rectified_projection` ([K | 0] for pinhole models)."""
    del camera_name  # CameraInfo has no name field; it goes to the YAML
    msg = CameraInfo(header=header, height=int(res.height), width=int(res.width), distortion_model=res.model)
    msg.d = [float(v) for v in res.D]
    msg.k = [float(v) for v in res.K.ravel()]
    msg.r = [float(v) for v in np.eye(3).ravel()]
    msg.p = [float(v) for v in rectified_projection(res.camera()).ravel()]
    return msg


def image_msg(img: np.ndarray, header: Any) -> Image:
    return Image(header=header, **grey_to_image_fields(img))


def compressed_msg(data: bytes, fmt: str, header: Any) -> CompressedImage:
    msg = CompressedImage(header=header, format=fmt)
    msg.data = data
    return msg
