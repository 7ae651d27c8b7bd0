"""A robot cell from a client node: an arm resting at one pose of a simulated session, its tool pose
published at 20 Hz and its camera's frame at ``frame_hz`` (5 Hz), stamped now; ``capture(k)`` moves to pose k,
waits for the rest and calls ``~/capture``. Used by the session tests (test/ros/test_ros_session.py)
and the fault study (tools/fault_study.py). Import it with tools/ on ``sys.path``."""

from __future__ import annotations

from typing import Any

import numpy as np

from pascal_calib_ros.geometry.transform import Transform

RosClient = Any  # node_processes.RosClient


class Cell:
    """An arm resting at pose :attr:`k` of a simulated session: its tool pose at 20 Hz and its
    camera's frame at ``frame_hz`` (5 Hz), stamped now + :attr:`shift_ns` (a recording replayed with its own stamps:
    set it back to loop), from the client node."""

    def __init__(self, client: RosClient, images: list[np.ndarray], poses: list[Transform], frame_hz: float = 5.0
                 ) -> None:
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import Image

        from pascal_calib_ros.io.image_msgs import grey_to_image_fields

        self.client, self.k, self.ticks, self.shift_ns = client, 0, 0, 0
        self.every = max(1, round(20.0 / frame_hz))  # frames every this many 20 Hz ticks
        self.fields = [grey_to_image_fields(im) for im in images]
        self.poses = poses
        self.pub_pose = client.node.create_publisher(PoseStamped, "/tool_pose", 50)
        self.pub_img = client.node.create_publisher(Image, "/image", 5)
        client.node.create_timer(0.05, self.tick)

    def tick(self) -> None:
        from sensor_msgs.msg import Image

        self.ticks += 1
        stamp = self.stamp()
        self.pose(stamp)
        if self.ticks % self.every == 0:
            img = Image(**self.fields[self.k])
            img.header.stamp, img.header.frame_id = stamp, "camera"
            self.pub_img.publish(img)

    def stamp(self, extra_ns: int = 0) -> Any:
        from builtin_interfaces.msg import Time

        t = self.client.node.get_clock().now().nanoseconds + self.shift_ns + extra_ns
        return Time(sec=t // 10**9, nanosec=t % 10**9)

    def pose(self, stamp: Any) -> None:
        """Publish the tool pose of :attr:`k` with ``stamp``."""
        from geometry_msgs.msg import PoseStamped

        m = PoseStamped()
        m.header.frame_id, m.header.stamp = "base_link", stamp
        T = self.poses[self.k]
        (m.pose.position.x, m.pose.position.y, m.pose.position.z) = (float(x) for x in T.translation)
        q = T.quat
        (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w) = (float(x) for x in q)
        self.pub_pose.publish(m)

    def rest(self, k: int) -> None:
        """Move to pose k and rest there (frames of the new pose keep coming)."""
        self.k = k
        self.client.spin_until(lambda: False, 1.2)

    def capture(self, k: int) -> str:
        self.rest(k)
        r = self.client.call_trigger("/pascal_calib/capture", timeout=15)
        return f"{r.success} {r.message}"
