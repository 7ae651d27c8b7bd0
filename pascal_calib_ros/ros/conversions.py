"""Core results <-> ROS messages."""

from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import Pose, PoseArray, TransformStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from ..geometry import Transform
from ..io import CameraInfoData, Suggestions, grey_to_image_fields


def camera_info_msg(info: CameraInfoData, header: Any) -> CameraInfo:
    """The CameraInfo message of a calibration's CameraInfo data (:func:`~..workflows.outputs.
    camera_info_data`: K, D and ``distortion_model`` of its lens model, R, and P the rectified
    projection, [K | 0] for pinhole models)."""
    msg = CameraInfo(header=header, height=int(info.height), width=int(info.width),
                     distortion_model=info.distortion_model)
    msg.d = [float(v) for v in np.ravel(info.D)]
    msg.k = [float(v) for v in np.ravel(info.K)]
    msg.r = [float(v) for v in np.ravel(info.R)]
    msg.p = [float(v) for v in np.ravel(info.projection)]
    return msg


def transform_msg(X: Transform, parent: str, child: str, stamp: Any) -> TransformStamped:
    """geometry_msgs/TransformStamped of X (``child``'s points into ``parent``)."""
    tf = TransformStamped(header=Header(stamp=stamp, frame_id=parent), child_frame_id=child)
    tr, r = tf.transform.translation, tf.transform.rotation
    tr.x, tr.y, tr.z = (float(v) for v in X.translation)
    r.x, r.y, r.z, r.w = (float(v) for v in X.quat)
    return tf


def pose_msg(T: Transform) -> Pose:
    """geometry_msgs/Pose of T (position = translation, orientation = its unit quaternion)."""
    p = Pose()
    p.position.x, p.position.y, p.position.z = (float(v) for v in T.translation)
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in T.quat)
    return p


def tool_poses_msg(s: Suggestions, header: Any) -> PoseArray:
    """geometry_msgs/PoseArray of the suggested tool poses, best first (empty for a person's
    suggestions); ``header.frame_id`` must be the robot's base frame."""
    return PoseArray(header=header, poses=[pose_msg(x.tool.pose) for x in s.suggestions if x.tool is not None])


def image_msg(img: np.ndarray, header: Any) -> Image:
    return Image(header=header, **grey_to_image_fields(img))


