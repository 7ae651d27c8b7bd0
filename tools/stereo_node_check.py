#!/usr/bin/env python3
"""The stereo node against the CLI, measured: a rendered stereo head (ring grid, baseline 12 cm,
2 degrees between the cameras) replayed by ``replay_node`` in lock-step through
``calibration_node`` in stereo mode, and ``pascal-calib stereo`` on the same folders, in one run.

Prints the largest difference between the node's and the CLI's K, D, R, P and rig transform, both
against the renderer's truth, the time per examined pair (lock-step: from the node's log), the
``~/calibrate`` time and the CLI's time (the two run one after the other, on the same cores).

    tools/in_netns .venv/bin/python tools/stereo_node_check.py [--shots 6] [--size 640x480] [--report]
"""

from __future__ import annotations

import argparse
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))

from node_processes import BIN, NodeProcess, RosClient

from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.stereo_yaml import read_stereo_yaml
from pascal_calib_ros.sim.rig import RigSpec, render_rig, stereo_pair, write_rig
from pascal_calib_ros.targets import resolve_target

GRID = "ring_grid_a4"


def _deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees((Rotation.from_matrix(a) * Rotation.from_matrix(b).inv()).magnitude()))


def _node_session(rig: Path, out: Path, report: bool) -> tuple[float, list[float], str]:
    """Replay + node; returns the ~/calibrate time, the intervals between stored shots and the answer."""
    dom = random.Random(os.getpid()).randint(101, 200)
    # without output_dir the files go to ~/.ros/camera_info/head/ (main() points HOME into the work folder)
    params = {"mode": "stereo", "target": GRID, "gamma": 2.2, "min_views": 3, "min_view_distance": 0.0,
              "camera_name": "head", **({"output_dir": str(out)} if report else {})}
    cal = NodeProcess("calibration_node", params, dom, rig.parent / "node.log")
    rep = NodeProcess("replay_node", {"left_source": str(rig / "left"), "right_source": str(rig / "right"),
                                      "exit_when_done": True}, dom, rig.parent / "replay.log")
    client = RosClient(dom)
    try:
        if not client.spin_until(lambda: rep.proc.poll() is not None, 300):
            raise SystemExit(f"the replay did not finish:\n{rep.log()}")
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import CameraInfo

        arrived: list[float] = []
        client.node.create_subscription(CameraInfo, "/pascal_calib/left/camera_info",
                                        lambda _m: arrived.append(time.perf_counter()),
                                        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
        client.spin_until(lambda: False, 1.0)
        t = time.perf_counter()
        r = client.call_trigger("/pascal_calib/calibrate", timeout=600.0)
        dt = time.perf_counter() - t
        if arrived:
            print(f"~/left/camera_info arrived {arrived[0] - t:.1f} s after the ~/calibrate call")
    finally:
        client.close()
        cal.stop()
        rep.stop()
    if not r.success:
        raise SystemExit(f"~/calibrate refused: {r.message}\n{cal.log()}")
    stamps = [float(m) for m in re.findall(r"\[(\d+\.\d+)\] \[pascal_calib\]: shot \d+ stored", cal.log())]
    return dt, list(np.diff(stamps)), r.message


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shots", type=int, default=6)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--report", action="store_true", help="the node keeps its frames and writes the reports too")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    work = Path(tempfile.mkdtemp(prefix="stereo_node_check_"))
    session = render_rig(resolve_target(GRID), RigSpec(stereo_pair(w, h), shots=a.shots, single_shots=1, seed=a.seed))
    write_rig(session, work / "rig")
    node_out = work / "node"
    if not a.report:
        os.environ["HOME"] = str(work / "home")  # the node's default output: ~/.ros/camera_info/head/
        node_out = work / "home" / ".ros" / "camera_info" / "head"
    t_node, intervals, answer = _node_session(work / "rig", node_out, a.report)
    t = time.perf_counter()
    cli = subprocess.run([str(BIN / "pascal-calib"), "stereo", "--target", GRID, "--left", str(work / "rig" / "left"),
                          "--right", str(work / "rig" / "right"), "-o", str(work / "cli"), "--gamma", "2.2",
                          "--min-views", "3", "--camera-name", "head"], capture_output=True, text=True)
    t_cli = time.perf_counter() - t
    if cli.returncode:
        raise SystemExit(cli.stdout + cli.stderr)
    print(f"{a.shots} shots + 1 for one camera at {w}x{h}, ring grid; work folder {work}")
    print(f"node answer: {answer}")
    diffs = {}
    for side in ("left", "right"):
        n, c = read_camera_yaml(node_out / f"{side}.yaml"), read_camera_yaml(work / "cli" / f"{side}.yaml")
        diffs[side] = max(float(np.abs(x - y).max()) for x, y in ((n.K, c.K), (n.D, c.D), (n.R, c.R),
                                                                  (n.projection, c.projection)))
    ns, cs = read_stereo_yaml(node_out / "stereo.yaml"), read_stereo_yaml(work / "cli" / "stereo.yaml")
    print(f"node - CLI: largest |difference| of K, D, R, P: left {diffs['left']:.3g}, right {diffs['right']:.3g}; "
          f"rig rotation {_deg(ns['rig'].R, cs['rig'].R):.3g} deg, translation "
          f"{1000 * np.linalg.norm(ns['rig'].translation - cs['rig'].translation):.3g} mm")
    truth = session.extrinsic(1)
    for name, st in (("node", ns), ("CLI", cs)):
        print(f"{name} vs truth: rig rotation {_deg(st['rig'].R, truth.R):.4f} deg, translation "
              f"{1000 * np.linalg.norm(st['rig'].translation - truth.translation):.4f} mm; sigma "
              f"{np.linalg.norm(st['sigma_rotation_deg']):.4f} deg, "
              f"{np.linalg.norm(st['sigma_translation_mm']):.4f} mm")
    for c, side in enumerate(("left", "right")):
        K, Kt = read_camera_yaml(node_out / f"{side}.yaml").K, session.spec.cameras[c].camera.K
        print(f"node {side}: fx {100 * (K[0, 0] / Kt[0, 0] - 1):+.4f} %, fy {100 * (K[1, 1] / Kt[1, 1] - 1):+.4f} %, "
              f"c {np.hypot(K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]):.3f} px from the truth")
    if intervals:
        print(f"lock-step: {np.median(intervals) * 1000:.0f} ms per stored pair (median of {len(intervals)}: "
              "receive, convert, detect both, store)")
    print(f"~/calibrate {t_node:.1f} s{' (with the reports)' if a.report else ''}; pascal-calib stereo {t_cli:.1f} s "
          "(reading and detection included)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
