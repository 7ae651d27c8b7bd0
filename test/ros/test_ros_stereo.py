"""The calibration node's stereo mode over real DDS (issue 25): a rendered stereo head replayed by
replay_node in lock-step gives the CLI's result (`pascal-calib stereo` on the same folders); both
CameraInfos and the rig transform are latched; ~/commit reaches each driver's own service; frames
that never pair, too few shots and a degenerate set are refused with the reason and the node
stays up; bad parameters stop it at start with the reason."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_harness import (
    NodeProcess,
    RosClient,
    latest_status,
    next_domain_id,
    require_netns,
    status_subscription,
    tf_static_echo,
)
from scipy.spatial.transform import Rotation

from pascal_calib_ros.cli import main as cli_main
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.images import read_grey
from pascal_calib_ros.io.stereo_yaml import read_stereo_yaml
from pascal_calib_ros.sim.rig import RigSession, RigSpec, render_rig, stereo_pair, write_rig
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]

GRID = "ring_grid_a4"
# 6 shots both cameras see and 1 placed for one camera (the detector finds it in neither: cut by the border)
SPEC = RigSpec(stereo_pair(640, 480), shots=6, single_shots=1, seed=1)
NODE = {"mode": "stereo", "target": GRID, "gamma": 2.2, "min_views": 3, "min_view_distance": 0.0}


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RigSession]:
    out = tmp_path_factory.mktemp("stereo_rig")
    session = render_rig(resolve_target(GRID), SPEC)
    write_rig(session, out)
    return out, session


def _latched(client: RosClient, msg_type: Any, topic: str) -> list:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    got: list = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    client.node.create_subscription(msg_type, topic, got.append, qos)
    return got


def _driver(client: RosClient, service: str, accept: list[bool]) -> list:
    """A camera driver's set_camera_info service: records what it is sent, answers with accept[0]."""
    from sensor_msgs.srv import SetCameraInfo

    received: list = []

    def serve(req: SetCameraInfo.Request, resp: SetCameraInfo.Response) -> SetCameraInfo.Response:
        received.append(req.camera_info)
        resp.success, resp.status_message = accept[0], f"stored by {service}" if accept[0] else "read-only camera"
        return resp

    client.node.create_service(SetCameraInfo, service, serve)
    return received


def _cli(rig_dir: Path, out: Path) -> subprocess.Popen:
    """`pascal-calib stereo` on the rendered folders, with the node's options (run beside the node)."""
    exe = Path(sys.executable).parent / "pascal-calib"
    return subprocess.Popen([str(exe), "stereo", "--target", GRID, "--left", str(rig_dir / "left"), "--right",
                             str(rig_dir / "right"), "-o", str(out), "--gamma", "2.2", "--min-views", "3",
                             "--camera-name", "head"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _rotation_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees((Rotation.from_matrix(a) * Rotation.from_matrix(b).inv()).magnitude()))


def test_replayed_stereo_session_gives_the_cli_result_and_commits_to_each_driver(
        tmp_path: Path, rig: tuple[Path, RigSession]) -> None:
    from geometry_msgs.msg import TransformStamped
    from sensor_msgs.msg import CameraInfo, Image

    from pascal_calib_ros.session.overlay import panel_width

    rig_dir, session = rig
    cli = _cli(rig_dir, tmp_path / "cli")
    dom = next_domain_id()
    out = tmp_path / "node"
    cal = NodeProcess("calibration_node", {**NODE, "output_dir": str(out), "camera_name": "head",
                                           "left_set_camera_info_service": "/head/left/set_camera_info",
                                           "right_set_camera_info_service": "/head/right/set_camera_info"},
                      dom, tmp_path / "cal.log")
    client = RosClient(dom)
    rep = None
    try:
        status = status_subscription(client)
        pictures: list = []
        client.node.create_subscription(Image, "/pascal_calib/detections", pictures.append, 10)
        # the node draws ~/detections only for a subscriber it knows: connected before the replay starts
        assert client.spin_until(lambda: client.node.count_publishers("/pascal_calib/detections") > 0, 30), cal.log()
        rep = NodeProcess("replay_node", {"left_source": str(rig_dir / "left"), "right_source": str(rig_dir / "right"),
                                          "exit_when_done": True}, dom, tmp_path / "rep.log")
        assert client.spin_until(lambda: rep.proc.poll() is not None, 90), rep.log()
        assert rep.wait(1) == 0, rep.log()
        assert "replaying 7 stereo shot(s)" in rep.log() and "14 examined by the calibration node" in rep.log()
        assert client.spin_until(lambda: latest_status(status).get("pairs_examined") == "7", 10), cal.log()
        st = latest_status(status)
        assert st["shots_both"] == "6" and st["frames_unpaired_left"] == "0" and st["pairs_dropped"] == "0", st
        # ~/detections: both cameras side by side, each with its panel
        assert pictures and (pictures[-1].width, pictures[-1].height) == (2 * (640 + panel_width(480)), 480)
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "no calibration to commit" in r.message
        r = client.call_trigger("/pascal_calib/calibrate", timeout=240.0)
        assert r.success, r.message + cal.log()
        assert "X_right = R X_left + T" in r.message and "shots=6 both/6" in r.message, r.message
        # subscribed after the result: transient local delivers it
        infos = [_latched(client, CameraInfo, f"/pascal_calib/{side}/camera_info") for side in ("left", "right")]
        tf = _latched(client, TransformStamped, "/pascal_calib/stereo_transform")
        assert client.spin_until(lambda: bool(infos[0] and infos[1] and tf), 20), cal.log()
        # /tf_static: a tf2 listener started after the broadcast, in its own process
        echoed = tf_static_echo(dom, ["right_camera_optical_frame"])
        assert echoed["rc"] == 0, echoed["output"] + cal.log()
        # ~/commit: each camera's CameraInfo to its own driver, both answers reported
        accept = [True]
        sent = [_driver(client, f"/head/{side}/set_camera_info", [True] if side == "left" else accept)
                for side in ("left", "right")]
        r = client.call_trigger("/pascal_calib/commit")
        assert r.success, r.message
        assert "left (/head/left/set_camera_info): driver accepted the calibration: stored by /head/left" in r.message
        assert "right (/head/right/set_camera_info): driver accepted" in r.message, r.message
        accept[0] = False
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "read-only camera" in r.message and "only one camera holds" in r.message, r.message
    finally:
        client.close()
        if rep is not None:
            rep.stop()
        assert cal.stop() == 0, cal.log()
    assert cli.wait(240) == 0, cli.stdout.read() if cli.stdout else ""

    # the node's files and messages against the CLI's files: the same calibration
    for c, side in enumerate(("left", "right")):
        mine, theirs = read_camera_yaml(out / f"{side}.yaml"), read_camera_yaml(tmp_path / "cli" / f"{side}.yaml")
        assert mine.camera_name == theirs.camera_name == f"head/{side}"
        np.testing.assert_allclose(mine.K, theirs.K, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(mine.D, theirs.D, rtol=0, atol=1e-10)
        np.testing.assert_allclose(mine.R, theirs.R, rtol=0, atol=1e-10)
        np.testing.assert_allclose(mine.projection, theirs.projection, rtol=1e-9, atol=1e-8)
        msg = infos[c][-1]
        np.testing.assert_allclose(np.reshape(msg.k, (3, 3)), mine.K, rtol=1e-12)
        np.testing.assert_allclose(np.reshape(msg.p, (3, 4)), mine.projection, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(msg.d, mine.D, rtol=1e-12, atol=1e-15)
        assert (msg.width, msg.height, msg.distortion_model) == (640, 480, "plumb_bob")
        # each driver got its own camera's calibration
        np.testing.assert_allclose(np.reshape(sent[c][0].k, (3, 3)), mine.K, rtol=1e-12)
        assert (sent[c][0].p[3] < -1.0) if side == "right" else (sent[c][0].p[3] == 0.0)
        assert len(sorted((out / side).glob("*.png"))) == 6
        assert (out / f"{side}.calibration.json").is_file()
    mine_st, cli_st = read_stereo_yaml(out / "stereo.yaml"), read_stereo_yaml(tmp_path / "cli" / "stereo.yaml")
    assert _rotation_deg(mine_st["rig"].R, cli_st["rig"].R) < 1e-7
    assert 1000 * np.linalg.norm(mine_st["rig"].translation - cli_st["rig"].translation) < 1e-6
    # the transform message: the right optical frame in the left's, the inverse of X_right = R X_left + T
    t = tf[-1]
    assert (t.header.frame_id, t.child_frame_id) == ("left_camera_optical_frame", "right_camera_optical_frame")
    q = t.transform.rotation
    R_msg = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    tr = t.transform.translation
    E = mine_st["rig"]
    assert _rotation_deg(R_msg, E.R.T) < 1e-6
    np.testing.assert_allclose([tr.x, tr.y, tr.z], -E.R.T @ E.translation, atol=1e-9)
    # the same transform on /tf_static (and nothing else from this node)
    sent = echoed["by_child"]["right_camera_optical_frame"]
    assert sent["parent"] == "left_camera_optical_frame" and len(echoed["transforms"]) == 1, echoed
    np.testing.assert_allclose(sent["translation"], [tr.x, tr.y, tr.z], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sent["rotation"], [q.x, q.y, q.z, q.w], rtol=0, atol=1e-12)
    # and both against the rendered truth (a sanity check: the tight figures are the stereo workflow's tests)
    truth = session.extrinsic(1)
    assert _rotation_deg(E.R, truth.R) < 0.05 and 1000 * np.linalg.norm(E.translation - truth.translation) < 0.5
    assert (out / "report" / "stereo.pdf").is_file()


def _image(img: np.ndarray, stamp_ns: int, frame_id: str) -> Any:
    from sensor_msgs.msg import Image

    from pascal_calib_ros.io.image_msgs import grey_to_image_fields

    msg = Image(**grey_to_image_fields(img))
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_ns // 10**9, stamp_ns % 10**9
    msg.header.frame_id = frame_id
    return msg


def _set_parameter(client: RosClient, name: str, value: float) -> Any:
    """Set one double parameter of the node through its set_parameters service; the SetParametersResult."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    cli = client.node.create_client(SetParameters, "/pascal_calib/set_parameters")
    assert client.spin_until(cli.service_is_ready, 10)
    client.spin_until(lambda: False, 0.5)  # let the response reader match (see RosClient.call_trigger)
    req = SetParameters.Request(parameters=[Parameter(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_DOUBLE, double_value=value))])
    fut = cli.call_async(req)
    assert client.spin_until(fut.done, 10)
    return fut.result().results[0]


def test_frames_that_never_pair_too_few_shots_and_a_degenerate_set_are_refused(
        tmp_path: Path, rig: tuple[Path, RigSession]) -> None:
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    rig_dir, _ = rig
    shots = [[read_grey(rig_dir / side / f"shot_{k:03d}.png") for side in ("left", "right")] for k in range(3)]
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", NODE, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        # the right driver publishes best effort: the node matches each topic's QoS on its own
        best_effort = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
        pubs = [client.node.create_publisher(Image, "/left/image", 5),
                client.node.create_publisher(Image, "/right/image", best_effort)]
        assert client.spin_until(lambda: all(p.get_subscription_count() for p in pubs), 30), cal.log()
        client.spin_until(lambda: False, 0.5)
        t0 = time.time_ns()

        def send(left: int, right: int, t_left: int, t_right: int) -> None:
            pubs[0].publish(_image(shots[left][0], t_left, "l"))
            pubs[1].publish(_image(shots[right][1], t_right, "r"))
            client.spin_until(lambda: False, 0.3)

        # the right camera's stamps are 0.5 s behind: no pair, and the status says why
        for k in range(4):
            send(k % 3, k % 3, t0 + k * 10**9, t0 + k * 10**9 + 5 * 10**8)
        assert client.spin_until(lambda: "never pair" in latest_status(status).get("sync_note", ""), 10), cal.log()
        st = latest_status(status)
        assert "their stamps differ by 0.500 s, more than sync_slop 0.02 s" in st["sync_note"], st
        assert status[-1].status[0].level == DiagnosticStatus.ERROR and st["pairs"] == "0", status[-1].status[0]
        assert (st["qos_left"], st["qos_right"]) == ("reliable", "best_effort")
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "0 shot(s) seen by both cameras; need 3" in r.message, r.message
        assert "frames arrive but never pair" in r.message and "0.500 s" in r.message, r.message
        # two shots that pair: still too few
        for k in range(2):
            send(k, k, t0 + (10 + k) * 10**9, t0 + (10 + k) * 10**9)
        assert client.spin_until(lambda: latest_status(status).get("shots_both") == "2", 20), cal.log()
        assert latest_status(status)["sync_note"] == ""
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "2 shot(s) seen by both cameras; need 3" in r.message, r.message
        # three shots of one pose: degenerate, refused by the calibration with its reason
        assert client.call_trigger("/pascal_calib/reset").success
        for k in range(3):
            send(0, 0, t0 + (20 + k) * 10**9, t0 + (20 + k) * 10**9 + 10**6)  # 1 ms apart: within the slop
        assert client.spin_until(lambda: latest_status(status).get("shots_both") == "3", 20), cal.log()
        r = client.call_trigger("/pascal_calib/calibrate", timeout=120.0)
        assert not r.success and "degenerate set of views" in r.message and "nothing published" in r.message, r.message
        # the node is still up and serving
        n = len(status)
        assert client.spin_until(lambda: len(status) > n + 1, 5)
        assert client.node.count_publishers("/pascal_calib/left/camera_info") == 1
        # at run time: a negative slop is refused; a slop above the stamp difference pairs those frames
        assert not _set_parameter(client, "sync_slop", -1.0).successful
        assert _set_parameter(client, "sync_slop", 0.6).successful
        send(1, 1, t0 + 30 * 10**9, t0 + 30 * 10**9 + 5 * 10**8)
        assert client.spin_until(lambda: latest_status(status).get("shots_both") == "4", 20), cal.log()
        assert latest_status(status)["last_pair_stamp_difference_s"] == "0.500000"
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
    assert "stereo calibration refused" in cal.log()


def test_stereo_bag_replay_pairs_unsynchronised_frames(tmp_path: Path, rig: tuple[Path, RigSession]) -> None:
    """A bag of two image topics, the right camera 5 ms behind: the replay pairs them by recorded stamp
    and the node stores the same shots as from the folders (no frame unpaired or dropped)."""
    rig_dir, _ = rig
    bag = tmp_path / "bag"
    assert cli_main(["bag", "--out", str(bag), "--left", str(rig_dir / "left"), "--right", str(rig_dir / "right"),
                     "--storage", "mcap", "--compressed", "--right-delay", "0.005"]) == 0
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {**NODE, "transport": "compressed"}, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(bag), "left_bag_topic": "/left/image_raw",
                                      "right_bag_topic": "/right/image_raw", "exit_when_done": True},
                      dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: rep.proc.poll() is not None, 90), rep.log()
        assert rep.wait(1) == 0, rep.log()
        assert client.spin_until(lambda: latest_status(status).get("pairs_examined") == "7", 10), cal.log()
        st = latest_status(status)
        assert st["shots_both"] == "6" and st["frames_unpaired_left"] == st["frames_unpaired_right"] == "0", st
        assert "as sensor_msgs/CompressedImage on /left/image/compressed, /right/image/compressed" in rep.log()
    finally:
        client.close()
        rep.stop()
        assert cal.stop() == 0, cal.log()


@pytest.mark.parametrize(("params", "expected"), [
    ({"mode": "triple"}, "mode='triple' is not one of 'mono', 'stereo'"),
    ({"mode": "stereo", "sync_slop": -0.5}, "invalid parameter sync_slop"),
    ({"mode": "stereo", "left_set_camera_info_service": "cam/set_camera_info",
      "right_set_camera_info_service": "cam/set_camera_info"}, "one service would write both calibrations"),
])
def test_invalid_stereo_parameters_refuse_to_start(tmp_path: Path, params: dict, expected: str) -> None:
    cal = NodeProcess("calibration_node", params, next_domain_id(), tmp_path / "cal.log")
    assert cal.wait(30) == 2, cal.log()
    assert expected in cal.log(), cal.log()
