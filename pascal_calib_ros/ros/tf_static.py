"""Static transforms on ``/tf_static`` (tf2_msgs/msg/TFMessage), where MoveIt, RViz and tf2 listeners look.

As ``tf2_ros.StaticTransformBroadcaster`` does: one reliable, transient-local publisher of depth 1 (a
listener that starts later still gets it), every static transform this node broadcasts in one
message, re-sent whole when one is added or changes (keyed by child frame). Where ``tf2_ros`` is
installed (a ROS install) its broadcaster is used; otherwise ``tf2_msgs`` (built into the venv by
``tools/build_msg_package.py``: no wheel on PyPI) is published directly with the same QoS. Without
either nothing is broadcast, and :attr:`StaticTransforms.unavailable` says why (the node logs it once
and reports it in its answers); the latched result topics are unaffected.
"""

from __future__ import annotations

import threading
from typing import Any

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

TF_STATIC = "/tf_static"
# the QoS of tf2_ros's StaticTransformBroadcaster (and what its listeners ask for)
STATIC_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                        history=HistoryPolicy.KEEP_LAST)


class StaticTransforms:
    """The node's static transforms on ``/tf_static``."""

    def __init__(self, node: Node) -> None:
        self._lock = threading.Lock()
        self._by_child: dict[str, TransformStamped] = {}
        self._broadcaster: Any = None
        self._publisher: Any = None
        self._message_type: Any = None
        self.unavailable = ""
        self.via = ""
        try:
            from tf2_ros import StaticTransformBroadcaster

            self._broadcaster = StaticTransformBroadcaster(node, qos=STATIC_QOS)
            self.via = "tf2_ros.StaticTransformBroadcaster"
            return
        except ImportError:
            pass
        try:
            from tf2_msgs.msg import TFMessage
        except ImportError as e:
            self.unavailable = (f"{TF_STATIC} is not broadcast: neither tf2_ros nor tf2_msgs can be imported ({e}); "
                                "in a ROS install: apt install ros-$ROS_DISTRO-tf2-ros; in the PyPI venv: "
                                "tools/build_msg_package.py (make venv runs it)")
            return
        self._message_type = TFMessage
        self._publisher = node.create_publisher(TFMessage, TF_STATIC, STATIC_QOS)
        self.via = "tf2_msgs/msg/TFMessage"

    @property
    def transforms(self) -> list[TransformStamped]:
        """What is broadcast now (one per child frame)."""
        with self._lock:
            return list(self._by_child.values())

    def send(self, *transforms: TransformStamped) -> bool:
        """Add or replace ``transforms`` (by child frame) and broadcast the whole set; False (nothing
        sent) when ``/tf_static`` is unavailable (:attr:`unavailable`)."""
        if self.unavailable:
            return False
        with self._lock:
            for t in transforms:
                self._by_child[t.child_frame_id] = t
            current = list(self._by_child.values())
            if self._broadcaster is not None:
                self._send_with_tf2_ros(current)
            else:
                self._publisher.publish(self._message_type(transforms=current))
        return True

    def _send_with_tf2_ros(self, current: list[TransformStamped]) -> None:
        """The whole set through tf2_ros's broadcaster. Some of its versions keep the first transform sent for
        a child frame and ignore a new one (they only append unseen children): then its message is set to the
        current set and sent again, so that a recalibration replaces the old transform."""
        b = self._broadcaster
        b.sendTransform(current)
        net = getattr(b, "net_message", None)
        if net is not None and hasattr(b, "pub_tf") and list(net.transforms) != current:
            net.transforms = current
            b.pub_tf.publish(net)

    def describe(self) -> str:
        """For ``~/status``: ``tool0 -> camera_optical_frame`` (every broadcast transform, parent -> child),
        empty before the first, or why nothing can be broadcast."""
        if self.unavailable:
            return self.unavailable
        return ", ".join(f"{t.header.frame_id} -> {t.child_frame_id}" for t in self.transforms)
