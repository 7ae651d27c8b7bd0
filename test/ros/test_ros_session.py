"""A session nothing loses (issue 34), through the real node over DDS: an arm session written view
by view into its session folder, the node killed with SIGKILL in the middle, started again with
``resume:=true``: the same views, and the hand-eye result ``pascal-calib handeye SESSION``
computes offline from the folder; a node started on a folder that holds views without
``resume`` refuses to start, with the reason; ``~/reset`` clears the latched suggested poses."""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros_harness import NodeProcess, RosClient, latest_status, next_domain_id, require_netns, status_subscription

from pascal_calib_ros.cli import main as cli_main
from pascal_calib_ros.io.session_folder import SessionFolder
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]  # the real nodes over DDS (make test: inside tools/in_netns)

VIEWS = 7


@pytest.fixture(scope="module")
def arm() -> object:
    from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session

    return simulate_arm_session(resolve_target("ring_a4"), ArmSpec(mode="eye_in_hand", views=VIEWS, width=640,
                                                                   height=480, k1=-0.1, seed=3))


def _node(params: dict, dom: int, log: Path) -> NodeProcess:
    return NodeProcess("calibration_node", {"collect": "on_capture", "robot_pose_topic": "/tool_pose",
                                            "hand_eye": "eye_in_hand", "min_views": 6, "capture_timeout": 5.0,
                                            **params}, dom, log)


def test_a_killed_arm_session_resumes_with_the_same_views(tmp_path: Path, arm) -> None:
    from arm_cell import Cell  # tools/ (on sys.path through ros_harness)

    sim = arm
    images, poses = sim.images["ring_a4"], sim.robot_poses  # type: ignore[attr-defined]
    session, out = tmp_path / "session", tmp_path / "out"
    params = {"session_dir": str(session), "output_dir": str(out)}
    dom = next_domain_id()
    client = RosClient(dom)
    cell = Cell(client, images, poses)
    first = _node(params, dom, tmp_path / "a.log")
    second = None
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: latest_status(status).get("session_folder") == str(session), 30), first.log()
        answers = [cell.capture(k) for k in range(4)]
        assert all(a.startswith("True view ") for a in answers), f"{answers}\n{first.log()}"
        first.proc.send_signal(signal.SIGKILL)  # the process dies at view 4 of 7
        first.proc.wait(10)
        assert len(SessionFolder.open(session).views) == 4
        # started again on a folder with views, without resume: refused, the views untouched
        refused = _node(params, dom, tmp_path / "b.log")
        assert refused.proc.wait(30) == 2, refused.log()
        assert "already holds a session with views: continue it (resume)" in refused.log(), refused.log()
        second = _node({**params, "resume": True}, dom, tmp_path / "c.log")
        # the resumed node's own status (the killed node's last ones may still be on their way)
        assert client.spin_until(lambda: "4 view(s) resumed" in second.log(), 120), second.log()
        started = client.node.get_clock().now().nanoseconds

        def resumed() -> bool:
            fresh = [m for m in status if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec > started]
            return bool(fresh) and {kv.key: kv.value for kv in fresh[-1].status[0].values}.get(
                "views_with_robot_pose") == "4"
        assert client.spin_until(resumed, 60), f"{latest_status(status)}\n{second.log()}"
        answers = [cell.capture(k) for k in range(4, VIEWS)]
        assert all(a.startswith("True view ") for a in answers), f"{answers}\n{second.log()}"
        r = client.call_trigger("/pascal_calib/calibrate", timeout=120)
        assert r.success, f"{r.message}\n{second.log()}"
        recorded = SessionFolder.open(session)
        assert [v.name for v in recorded.views] == sorted({v.name for v in recorded.views}) and len(
            recorded.views) == VIEWS
        for v, T in zip(recorded.views, poses, strict=True):  # the robot pose of each view, as the arm sent it
            assert v.robot_pose is not None and np.allclose(v.robot_pose.matrix, T.matrix, atol=1e-12)
        node_he = yaml.safe_load((out / "hand_eye.yaml").read_text())
        assert cli_main(["handeye", "-o", str(tmp_path / "offline" / "cam.yaml"), str(session)]) == 0
        offline = yaml.safe_load((tmp_path / "offline" / "hand_eye.yaml").read_text())
        np.testing.assert_allclose(node_he["translation"], offline["translation"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(node_he["rotation"], offline["rotation"], rtol=0, atol=1e-9)
        assert node_he["views_used"] == offline["views_used"]
    finally:
        client.close()
        if second is not None:
            assert second.stop() == 0, second.log()
