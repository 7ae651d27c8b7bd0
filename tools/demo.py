#!/usr/bin/env python3
"""``make demo``: our own sample views through the real nodes.

Renders a sample session of the ring target (12 good views and 3 that must be rejected: cut by
the border, empty, defocused), starts ``replay_node`` (lock-step: every frame is examined) and
``calibration_node`` as processes, follows ``~/status``, calls ``~/calibrate``, receives the
latched ``~/camera_info`` in a separate subscriber, prints it and its error against the
renderer's ground truth, and stops the nodes. Runs in a private network namespace when possible:
``tools/in_netns .venv/bin/python tools/demo.py``.
"""

from __future__ import annotations

import json
import os
import random
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from node_processes import NodeProcess, RosClient

from pascal_calib_ros.sim.ground_truth import errors_against_truth
from pascal_calib_ros.sim.session import SessionSpec, render_session
from pascal_calib_ros.targets import resolve_target

OUT = Path("demo_out")


def main() -> int:
    session = OUT / "session"
    spec = SessionSpec(width=800, height=600, k1=-0.25, views=12, blur=1.0, gamma=2.2, noise=1.5, seed=3,
                       cut_views=1, empty_views=1, defocused_views=1)
    if not (session / "session.json").exists():
        print(f"rendering sample views into {session}/ (12 good views + 3 that must be rejected)")
        render_session(resolve_target("ring_a4"), spec, session)
    truth = json.loads((session / "session.json").read_text())
    domain = int(os.environ.get("ROS_DOMAIN_ID", "")) if os.environ.get("ROS_DOMAIN_ID") else random.randint(1, 100)
    print(f"starting calibration_node and replay_node (ROS_DOMAIN_ID={domain}, discovery on localhost)")
    cal = NodeProcess("calibration_node",
                      {"min_views": 8, "camera_name": "demo_camera", "output_dir": str(OUT / "calibration")},
                      domain, OUT / "calibration_node.log")
    # lock-step (the default): each frame once the calibration node has examined the previous one
    rep = NodeProcess("replay_node", {"source": str(session), "mode": "lockstep", "wait_for_subscribers": 1,
                                      "exit_when_done": True}, domain, OUT / "replay_node.log")
    client = RosClient(domain, "demo_client")
    code = 1
    try:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import CameraInfo

        status: list[Any] = []
        client.node.create_subscription(DiagnosticArray, "/pascal_calib/status", status.append, 10)

        def kv() -> dict[str, str]:
            return {v.key: v.value for v in status[-1].status[0].values} if status else {}

        last = ""

        def done() -> bool:
            nonlocal last
            if status and status[-1].status[0].message != last:
                last = status[-1].status[0].message
                print(f"  status: {last}")
            return rep.proc.poll() is not None and kv().get("frames_received") == str(len(truth["images"]))

        if not client.spin_until(done, 90):
            print("demo: the replay did not reach the calibration node\n" + cal.log() + rep.log(), file=sys.stderr)
            return 1
        client.spin_until(lambda: False, 0.5)  # let the last status arrive
        print("  rejected: " + ", ".join(f"{k[10:]} x{v}" for k, v in kv().items() if k.startswith("rejected: ")))
        print("$ call /pascal_calib/calibrate (std_srvs/Trigger)")
        resp = client.call_trigger("/pascal_calib/calibrate")
        print(f"  success={resp.success} message={resp.message!r}")
        if not resp.success:
            return 1
        infos: list[Any] = []
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        client.node.create_subscription(CameraInfo, "/pascal_calib/camera_info", infos.append, qos)
        if not client.spin_until(lambda: bool(infos), 10):
            print("demo: no CameraInfo received", file=sys.stderr)
            return 1
        m = infos[-1]
        print("/pascal_calib/camera_info (sensor_msgs/CameraInfo, received by a late subscriber):")
        print(f"  width={m.width} height={m.height} distortion_model={m.distortion_model}")
        print("  k=[" + ", ".join(f"{v:.3f}" for v in m.k) + "]")
        print("  d=[" + ", ".join(f"{v:.5f}" for v in m.d) + "]")
        print("  p=[" + ", ".join(f"{v:.3f}" for v in m.p) + "]")
        err = errors_against_truth(truth, np.array(m.k).reshape(3, 3), np.array(m.d))
        print("error against the renderer's ground truth:")
        print(f"  fx {err['fx_err_pct']:+.4f} %   fy {err['fy_err_pct']:+.4f} %   principal point "
              f"({err['cx_err_px']:+.2f}, {err['cy_err_px']:+.2f}) px   model error {err['model_err_px']:.3f} px")
        print(f"YAML and accepted frames: {OUT / 'calibration'}/")
        pp = float(np.hypot(err["cx_err_px"], err["cy_err_px"]))
        ok = abs(err["fx_err_pct"]) < 0.1 and abs(err["fy_err_pct"]) < 0.1 and pp < 1.0
        print("demo: OK" if ok else "demo: accuracy outside the documented bounds")
        code = 0 if ok else 1
    finally:
        client.close()
        rc_cal, rc_rep = cal.stop(), rep.stop()
        if rc_cal != 0:
            print(f"calibration_node exited with {rc_cal}; see {cal.log_path}", file=sys.stderr)
            code = 1
        if rc_rep != 0:
            print(f"replay_node exited with {rc_rep}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
