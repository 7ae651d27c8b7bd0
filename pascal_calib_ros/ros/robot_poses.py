"""The robot's tool poses on a topic (geometry_msgs/PoseStamped or TransformStamped) into the live
session's pose buffer: the type detected once a publisher shows it, poses in other frames ignored,
counted and reported. TF lookup needs tf2_ros, which has no PyPI wheel: the pose topic is the
supported, tested path."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..geometry import Transform, TransformError
from ..session import PoseBuffer
from .guard import guarded_callback

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"


class RobotPoseInput:
    """Subscribes ``topic`` on ``node`` once its type is known and fills :attr:`poses`."""

    def __init__(self, node: Node, topic: str, frames: Callable[[], tuple[str, str]]) -> None:
        self.node, self.topic = node, topic
        self.frames = frames  # (robot base frame, tool frame), read at each pose (parameters may change)
        self.poses = PoseBuffer()
        self.sub: Any = None
        self.type = ""
        self.error = ""
        self.ignored = 0
        self._group = MutuallyExclusiveCallbackGroup()
        self.subscribe()
        node.create_timer(0.5, guarded_callback(node, "robot pose subscription", self.subscribe),
                          callback_group=MutuallyExclusiveCallbackGroup())

    @property
    def resolved(self) -> str:
        return self.node.resolve_topic_name(self.topic)

    def subscribe(self) -> None:
        """Subscribe once a publisher shows the topic's type (PoseStamped or TransformStamped); any
        other type is refused with the reason in the log and status."""
        if self.sub is not None:
            return
        name = self.resolved
        types = dict(self.node.get_topic_names_and_types()).get(name, [])
        if not types:
            return
        if POSE_STAMPED in types:
            from geometry_msgs.msg import PoseStamped as msg_type
            self.type = POSE_STAMPED
        elif TRANSFORM_STAMPED in types:
            from geometry_msgs.msg import TransformStamped as msg_type
            self.type = TRANSFORM_STAMPED
        else:
            error = (f"robot_pose_topic {name} has type {', '.join(types)}; expected {POSE_STAMPED} or "
                     f"{TRANSFORM_STAMPED}: no robot poses")
            if error != self.error:
                self.error = error
                self.node.get_logger().error(error)
            return
        infos = self.node.get_publishers_info_by_topic(name)
        best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
        qos = QoSProfile(depth=200, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE)
        self.sub = self.node.create_subscription(msg_type, self.topic,
                                                 guarded_callback(self.node, "robot pose callback", self.on_pose),
                                                 qos, callback_group=self._group)
        self.error = ""
        self.node.get_logger().info(f"robot poses: subscribed to {name} ({self.type}, "
                                    f"{'best-effort' if best_effort else 'reliable'})")

    def on_pose(self, msg: Any) -> None:
        base, tool = self.frames()
        fid = msg.header.frame_id.lstrip("/")
        child = getattr(msg, "child_frame_id", "").lstrip("/")
        if (fid and fid != base) or (child and child != tool):
            self.ignored += 1
            got = f"{fid or '?'} -> {child}" if child else f"frame {fid}"
            self.error = (f"robot poses on {self.resolved} are {got}, expected {base}"
                          f"{' -> ' + tool if child else ''} (robot_base_frame / robot_tool_frame): "
                          "ignored")
            self.node.get_logger().warn(self.error, throttle_duration_sec=5.0)
            return
        try:
            if hasattr(msg, "pose"):
                t, q = msg.pose.position, msg.pose.orientation
            else:
                t, q = msg.transform.translation, msg.transform.rotation
            T = Transform.from_quat((q.x, q.y, q.z, q.w), (t.x, t.y, t.z))
        except TransformError as e:
            self.ignored += 1
            self.error = f"robot pose ignored: {e}"
            self.node.get_logger().warn(self.error, throttle_duration_sec=5.0)
            return
        restarts = self.poses.restarts
        if not self.poses.add(int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec), T):
            self.error = self.poses.stamp_note  # set aside for its stamp (far from the frames')
            self.node.get_logger().warn(self.error, throttle_duration_sec=5.0)
            return
        if self.poses.restarts != restarts:
            self.node.get_logger().warn(self.poses.stamp_note)
        if self.error.startswith("robot pose"):  # the poses are usable again
            self.error = ""

    def status(self, views_with_pose: int) -> dict[str, Any]:
        """The robot poses' lines of ``~/status``."""
        return {"robot_pose_topic": self.resolved, "robot_pose_type": self.type or "unknown (no publisher seen)",
                "robot_poses_received": self.poses.received, "robot_poses_ignored": self.ignored,
                "robot_pose_error": self.error, "robot_pose_buffer": self.poses.describe(),
                "views_with_robot_pose": views_with_pose}
