"""Test-side helpers for the ROS end-to-end tests (node processes and the client node come from
tools/node_processes.py, shared with the demo and the load tests; not part of the package)."""

from __future__ import annotations

import itertools
import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))

from node_processes import NodeProcess, RosClient, ros_env

__all__ = ["NodeProcess", "RosClient", "camera_info_subscription", "latest_status", "next_domain_id",
           "require_netns", "status_subscription", "tf_static_echo"]

_domains = itertools.count(random.Random(os.getpid()).randint(1, 60))


def in_private_netns() -> bool:
    """True when this process only sees the loopback interface (``tools/in_netns``)."""
    try:  # /proc/net/dev is per network namespace (sysfs may still show the host's)
        lines = Path("/proc/net/dev").read_text().splitlines()[2:]
    except OSError:
        return False
    return {ln.split(":")[0].strip() for ln in lines} == {"lo"}


require_netns = pytest.mark.skipif(not in_private_netns(),
                                   reason="ROS end-to-end tests run only in a private network namespace "
                                          "(make test does it through tools/in_netns, as root)")


def next_domain_id() -> int:
    """A distinct ROS_DOMAIN_ID per test (and per test run: the base depends on the pid)."""
    return 1 + (next(_domains) % 100)


def status_subscription(client: RosClient) -> list:
    """Messages of /pascal_calib/status, appended as they arrive."""
    from diagnostic_msgs.msg import DiagnosticArray

    msgs: list = []
    client.node.create_subscription(DiagnosticArray, "/pascal_calib/status", msgs.append, 10)
    return msgs


def latest_status(msgs: list) -> dict[str, str]:
    """Key-values of the newest status message (empty before the first)."""
    return {kv.key: kv.value for kv in msgs[-1].status[0].values} if msgs else {}


def camera_info_subscription(client: RosClient) -> list:
    """A reliable, transient-local subscriber of /pascal_calib/camera_info (gets a latched result)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo

    got: list = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    client.node.create_subscription(CameraInfo, "/pascal_calib/camera_info", got.append, qos)
    return got


def tf_static_echo(domain_id: int, children: list[str], timeout: float = 20.0) -> dict:
    """A tf2 listener started now, in its own process (``tools/tf_static_echo.py``: a transient-local
    subscriber of tf2_msgs/msg/TFMessage on /tf_static), waiting for transforms to ``children``.
    Returns what it printed, ``{child: {"parent", "child", "translation", "rotation"}}`` under
    ``"by_child"``, with its exit code (``"rc"``, 0: all arrived) and its output (``"output"``)."""
    tool = Path(__file__).resolve().parents[1] / "tools" / "tf_static_echo.py"
    args = [sys.executable, str(tool), "--timeout", str(timeout), *(f"--child={c}" for c in children)]
    r = subprocess.run(args, env=ros_env(domain_id), capture_output=True, text=True, timeout=timeout + 60)
    lines = r.stdout.strip().splitlines()
    try:
        got = json.loads(lines[-1]) if lines else {}
    except json.JSONDecodeError:
        got = {}
    got["by_child"] = {t["child"]: t for t in got.get("transforms", [])}
    got["rc"], got["output"] = r.returncode, r.stdout + r.stderr
    return got
