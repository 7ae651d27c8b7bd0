"""Robot-arm sessions through the real nodes (separate processes, real DDS, private network
namespace): a recorded eye-in-hand session (images + geometry_msgs/PoseStamped in a bag written by
``pascal-calib bag --poses``) replayed with its recorded timing, ``~/capture`` at every pose as an
arm script would call it, ``~/calibrate`` with hand-eye, the latched ``~/hand_eye`` and
``~/camera_info`` received here; and a session whose target moves 2 px between frames, which
must store nothing and say "moving"."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from ros_harness import (
    NodeProcess,
    RosClient,
    camera_info_subscription,
    latest_status,
    next_domain_id,
    require_netns,
    status_subscription,
    tf_static_echo,
)

from pascal_calib_ros.cli import main as cli_main
from pascal_calib_ros.io.hand_eye_yaml import write_poses_yaml
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import Target, resolve_target

pytestmark = [require_netns, pytest.mark.ros]  # the real nodes over DDS (make test: inside tools/in_netns)

ARM_VIEWS = 7


@pytest.fixture(scope="module")
def ring() -> Target:
    return resolve_target("ring_a4")


@pytest.fixture(scope="module")
def arm_bag(tmp_path_factory: pytest.TempPathFactory, ring: Target) -> tuple[Path, object]:
    """An eye-in-hand session of the ring (640x480): every pose held 1 s, frames at 5 Hz, the
    tool pose at 20 Hz and at every frame (PoseStamped on /tool_pose)."""
    from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session

    out = tmp_path_factory.mktemp("arm_session")
    s = simulate_arm_session(ring, ArmSpec(mode="eye_in_hand", views=ARM_VIEWS, width=640, height=480, k1=-0.1,
                                           seed=3))
    paths = []
    for name, img in zip(s.names, s.images[ring.name], strict=True):
        cv2.imwrite(str(out / name), img)
        paths.append(out / name)
    write_poses_yaml(out / "POSES.yaml", "base_link", "tool0", dict(zip(s.names, s.robot_poses, strict=True)))
    bag = out / "bag"
    assert cli_main(["bag", "--out", str(bag), "--poses", str(out / "POSES.yaml"), "--rate", "5", "--hold", "1",
                     "--pose-topic", "/tool_pose", *map(str, paths)]) == 0
    return bag, s


def _hand_eye_subscription(client: RosClient) -> list:
    from geometry_msgs.msg import TransformStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    got: list = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    client.node.create_subscription(TransformStamped, "/pascal_calib/hand_eye", got.append, qos)
    return got


def test_arm_session_capture_and_hand_eye(tmp_path: Path, arm_bag: tuple[Path, object]) -> None:
    from geometry_msgs.msg import PoseStamped

    from pascal_calib_ros.geometry.transform import Transform
    from pascal_calib_ros.sim.arm import hand_eye_errors

    bag, s = arm_bag
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {
        "min_views": 6, "output_dir": str(tmp_path), "camera_name": "cam", "collect": "on_capture",
        "robot_pose_topic": "/tool_pose", "hand_eye": "eye_in_hand", "capture_timeout": 3.0},
        dom, tmp_path / "cal.log")
    client = RosClient(dom)
    rep = None
    try:
        status = status_subscription(client)
        poses: list = []  # the arm script follows the robot's pose
        client.node.create_subscription(PoseStamped, "/tool_pose", poses.append, 100)
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "Call ~/capture" in r.message, r.message
        # recorded timing; the script is listening before the arm starts
        rep = NodeProcess("replay_node", {"source": str(bag), "pose_topic": "/tool_pose", "mode": "timed",
                                          "rate": 0.0, "wait_for_subscribers": 1, "start_delay": 1.0,
                                          "exit_when_done": True}, dom, tmp_path / "rep.log")
        pose_type = "geometry_msgs/msg/PoseStamped"
        assert client.spin_until(lambda: latest_status(status).get("robot_pose_type") == pose_type, 30), (
            f"{latest_status(status)}\n{cal.log()}{rep.log()}")
        assert client.spin_until(lambda: bool(poses), 30), f"no robot pose received\n{cal.log()}{rep.log()}"
        answers: list[str] = []
        last: tuple[float, ...] | None = None
        while rep.proc.poll() is None or poses:
            if not client.spin_until(lambda: bool(poses), 3.0):
                break
            p = poses[-1].pose.position
            poses.clear()
            here = (round(p.x, 6), round(p.y, 6), round(p.z, 6))
            if here == last:
                continue
            last = here
            r = client.call_trigger("/pascal_calib/capture", timeout=10)
            answers.append(f"{r.success} {r.message}")
            poses.clear()  # the poses that came in while capturing belong to this rest
        stored = [a for a in answers if a.startswith("True view ")]
        assert len(stored) >= 6, f"{answers}\n{cal.log()}"
        assert all("target at (" in a and "tilt" in a and "robot tool at [" in a for a in stored), answers
        assert client.spin_until(
            lambda: latest_status(status).get("views_with_robot_pose") == str(len(stored)), 5), latest_status(status)
        r = client.call_trigger("/pascal_calib/calibrate", timeout=120)
        assert r.success, f"{r.message}\n{cal.log()}"
        assert r.message.startswith("hand_eye eye_in_hand: tool0 -> camera_optical_frame t=[") and "std=[" in r.message
        share = re.search(r"std=\[([^\]]+)\] mm \(arm accuracy share \[([^\]]+)\] mm\)", r.message)
        assert share, r.message  # the default arm accuracy's share: part of the std, never more
        assert all(0 < float(a) <= float(s) for s, a in zip(share[1].split(","), share[2].split(","), strict=True))
        used = re.search(r"views_used=(\d+)/(\d+)", r.message)
        assert used and int(used[2]) == len(stored) and int(used[1]) >= 5, r.message
        # received in this process (late subscribers: transient local)
        he = _hand_eye_subscription(client)
        info = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(he) and bool(info), 30), cal.log()
        m = he[-1]
        assert m.header.frame_id == "tool0" and m.child_frame_id == "camera_optical_frame"
        t, q = m.transform.translation, m.transform.rotation
        X = Transform.from_quat([q.x, q.y, q.z, q.w], [t.x, t.y, t.z])
        err_mm, err_deg, _, _ = hand_eye_errors(X, s.hand_eye)  # type: ignore[attr-defined]
        assert err_mm < 2.0 and err_deg < 0.2, (err_mm, err_deg, r.message)
        K, Kt = np.array(info[-1].k).reshape(3, 3), s.camera.K  # type: ignore[attr-defined]
        assert abs(K[0, 0] / Kt[0, 0] - 1) < 2e-3 and abs(K[1, 1] / Kt[1, 1] - 1) < 2e-3, K
        doc = yaml.safe_load((tmp_path / "hand_eye.yaml").read_text())
        assert doc["mode"] == "eye_in_hand" and doc["parent_frame"] == "tool0" and doc["target_frame"] == "base_link"
        np.testing.assert_allclose(doc["translation"], [t.x, t.y, t.z], atol=1e-9)
        # /tf_static: a tf2 listener started after the broadcast, in its own process, gets the same transform
        tf = tf_static_echo(dom, ["camera_optical_frame"])
        assert tf["rc"] == 0, tf["output"] + cal.log()
        sent = tf["by_child"]["camera_optical_frame"]
        assert sent["parent"] == "tool0" and len(tf["transforms"]) == 1, tf
        np.testing.assert_allclose(sent["translation"], doc["translation"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(sent["rotation"], doc["rotation"], rtol=0, atol=1e-9)
        assert latest_status(status).get("tf_static") == "tool0 -> camera_optical_frame", latest_status(status)
        assert (tmp_path / "cam.yaml").exists()
        assert rep.wait(30) == 0
        assert f"{ARM_VIEWS * 5} message(s) on /image" in rep.log() and " pose(s) on /tool_pose" in rep.log()
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
        if rep is not None:
            rep.stop()


def test_moving_target_is_never_stored(tmp_path: Path, ring: Target) -> None:
    """The target shifts 2 px between consecutive frames (a slow hand-held or conveyor motion):
    no frame is stored, automatically or by ~/capture; the status and the refusal say why."""
    cam = SessionSpec(width=640, height=480).camera()
    R = np.array([[1, 0, 0], [0, np.cos(0.35), -np.sin(0.35)], [0, np.sin(0.35), np.cos(0.35)]])
    img = render_view(ring, cam, Pose(R, np.array([0.02, -0.01, 0.8])), SensorModel(seed=5)).image
    frames = tmp_path / "frames"
    frames.mkdir()
    # looped: 2 px between consecutive frames, and no two frames alike, so that a frame the busy
    # detector skips never makes two equal frames neighbours (a back-and-forth pattern did: 8, 10, 8);
    # a loop of 4 s at 8 Hz, so that even a detector busy for a whole loop on a loaded machine (seen
    # with a 1.25 s loop) does not examine one frame twice in a row
    for k, shift in enumerate(range(0, 64, 2)):
        cv2.imwrite(str(frames / f"f{k:02d}.png"), np.roll(img, shift, axis=1))
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"min_views": 3, "max_motion_px": 0.5, "capture_timeout": 1.5,
                                           "calibration_file": str(tmp_path / "cam.yaml")}, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(frames), "mode": "timed", "rate": 8.0, "loop": True,
                                      "wait_for_subscribers": 1}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: int(latest_status(status).get("frames_examined", 0)) >= 8, 30), (
            f"{latest_status(status)}\n{cal.log()}{rep.log()}")
        r = client.call_trigger("/pascal_calib/capture")
        assert not r.success and "nothing stored within 1.5 s" in r.message, r.message
        assert re.search(r"moving \(target moved \d+\.\d", r.message) and "max_motion_px 0.5" in r.message, r.message
        assert client.spin_until(lambda: latest_status(status).get("captures_refused") == "1", 5)
        kv = latest_status(status)
        assert kv["views_accepted"] == "0" and int(kv["rejected: moving"]) >= 8, kv
        assert kv["captures_refused"] == "1" and kv["captures_stored"] == "0", kv
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "frame(s) were moving" in r.message and "'moving'" in r.message, r.message
        assert not (tmp_path / "cam.yaml").exists()
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
        rep.stop()


def test_lockstep_replay_of_an_arm_session_reproduces_it(tmp_path: Path, arm_bag: tuple[Path, object]) -> None:
    """Lock-step: every frame examined, the poses of a frame published before it: the first frame
    of every rest is "moving" (the arm came from the previous pose), the other 4 are still and
    carry their robot pose (automatic collection, no diversity threshold)."""
    bag, _ = arm_bag
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"min_views": 6, "robot_pose_topic": "/tool_pose", "min_view_distance": 0.0,
                                           "calibration_file": str(tmp_path / "cam.yaml")}, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(bag), "pose_topic": "/tool_pose", "exit_when_done": True},
                      dom, tmp_path / "rep.log")
    client = RosClient(dom)
    n_frames = ARM_VIEWS * 5
    try:
        status = status_subscription(client)
        assert rep.wait(60) == 0, rep.log()
        assert f"{n_frames} examined by the calibration node" in rep.log(), rep.log()
        assert client.spin_until(lambda: latest_status(status).get("frames_examined") == str(n_frames), 5)
        kv = latest_status(status)
        assert kv["rejected: moving"] == str(ARM_VIEWS) and kv["max_motion_px"] == "0.5", kv
        assert kv["views_accepted"] == str(n_frames - ARM_VIEWS) == kv["views_with_robot_pose"], str(kv)
        assert kv["frames_dropped"] == "0" and kv["robot_pose_error"] == "", kv
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
        rep.stop()
