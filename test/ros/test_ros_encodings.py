"""The running node takes the image encodings raw drivers publish (YUV 4:2:2 and 4:2:0, 16-bit
colour): each frame of a rendered session, sent in another encoding over DDS, is detected and
stored (real node, real DDS)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from encoded_images import encode_grey
from ros_harness import NodeProcess, RosClient, latest_status, next_domain_id, require_netns, status_subscription

from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]  # the real nodes over DDS (make test: inside tools/in_netns)

ENCODINGS = ["yuv422", "uyvy", "yuv422_yuy2", "yuyv", "nv12", "nv21", "rgb16", "bgr16", "rgba16", "bgra16"]


def test_node_detects_frames_in_every_raw_driver_encoding(tmp_path: Path) -> None:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    _, views = render_session_views(resolve_target("ring_a4"), SessionSpec(width=640, height=480,
                                                                           views=len(ENCODINGS), seed=21))
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"min_views": 3, "min_view_distance": 0.0}, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        examined: list = []
        qos = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        client.node.create_subscription(Header, "/pascal_calib/examined_frames", examined.append, qos)
        pub = client.node.create_publisher(Image, "/image", QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE))
        assert client.spin_until(lambda: pub.get_subscription_count() > 0, 20), cal.log()
        for k, (enc, view) in enumerate(zip(ENCODINGS, views, strict=True)):
            f = encode_grey(np.asarray(view.image, np.uint8), enc, pad=4 * (k % 2), big=k % 3 == 0, seed=k)
            msg = Image(height=f.height, width=f.width, encoding=f.encoding, is_bigendian=f.is_bigendian,
                        step=f.step, data=f.data)
            msg.header.stamp.sec = k + 1
            pub.publish(msg)  # lock-step: the next frame once this one is examined
            assert client.spin_until(lambda k=k: len(examined) > k, 30), f"{enc}: not examined\n{cal.log()}"
        assert client.spin_until(lambda: latest_status(status).get("frames_examined") == str(len(ENCODINGS)), 5)
        kv = latest_status(status)
        assert kv["frames_bad"] == "0" and kv["views_accepted"] == str(len(ENCODINGS)), kv
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
