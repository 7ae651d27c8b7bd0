#!/usr/bin/env python3
"""Listen on /tf_static as a tf2 listener does and print what arrives, as JSON (there is no ``ros2 topic
echo`` on PyPI). A reliable, transient-local subscription of tf2_msgs/msg/TFMessage, so a broadcast made
before this started is received too. Used by the end-to-end tests as the late subscriber in its own
process; the ROS environment (ROS_DOMAIN_ID, ...) comes from the caller.

    tools/tf_static_echo.py [--timeout 20] [--child FRAME ...]

Waits until transforms to every ``--child`` frame have arrived (without ``--child``: the first
message), then prints ``{"transforms": [{"parent", "child", "translation", "rotation"}, ...],
"messages": N, "publishers": N}`` (the newest transform per child frame; rotation x y z w) and exits 0;
exit 1 after ``--timeout`` seconds without them (what did arrive is printed all the same).
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--child", action="append", default=[], help="wait for a transform to this child frame")
    a = ap.parse_args(argv)

    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from tf2_msgs.msg import TFMessage

    rclpy.init()
    node = rclpy.create_node("tf_static_echo")
    latest: dict[str, dict] = {}
    count = [0]

    def on_message(msg: TFMessage) -> None:
        count[0] += 1
        for t in msg.transforms:
            tr, q = t.transform.translation, t.transform.rotation
            latest[t.child_frame_id] = {"parent": t.header.frame_id, "child": t.child_frame_id,
                                        "translation": [tr.x, tr.y, tr.z], "rotation": [q.x, q.y, q.z, q.w]}

    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     history=HistoryPolicy.KEEP_LAST)
    node.create_subscription(TFMessage, "/tf_static", on_message, qos)

    def done() -> bool:
        return all(c in latest for c in a.child) if a.child else count[0] > 0

    deadline = time.monotonic() + a.timeout
    while time.monotonic() < deadline and not done():
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({"transforms": list(latest.values()), "messages": count[0],
                      "publishers": node.count_publishers("/tf_static")}), flush=True)
    ok = done()
    node.destroy_node()
    rclpy.shutdown()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
