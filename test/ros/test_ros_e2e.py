"""Real nodes as separate processes over real DDS (Fast DDS), in a private network namespace:
replay -> calibration node -> ~/calibrate from this test -> CameraInfo checked against the
renderer's ground truth."""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

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
)

from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.io.bags import write_image_bag
from pascal_calib_ros.ros.replay_node import output_topic
from pascal_calib_ros.sim.session import SessionSpec, render_session
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]  # the real nodes over DDS (make test: inside tools/in_netns)


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ros_session")
    spec = SessionSpec(width=640, height=480, views=10, k1=-0.2, seed=21, empty_views=1)
    render_session(resolve_target("ring_a4"), spec, out)
    return out


def _truth(session: Path) -> dict:
    return json.loads((session / "session.json").read_text())


def _check_k(k: list[float] | np.ndarray, truth: dict, rel: float = 1e-3, pp_px: float = 1.5) -> None:
    K = np.asarray(k, float).reshape(3, 3)
    Kt = np.array(truth["K"])
    assert abs(K[0, 0] / Kt[0, 0] - 1) < rel and abs(K[1, 1] / Kt[1, 1] - 1) < rel, K
    assert np.hypot(K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]) < pp_px, K


# A 5 MP session of the experiment board. Its detection takes seconds per frame today (about
# 3.5 s on the 2-core CI machine), so the session is small and rendered at half size, then
# upscaled 2x to 2456x2058 (rendering at full size costs ~8 s per view): the frames have the
# size, bytes and content of a 5 MP session; the truth is K scaled by 2 (x' = 2 x + 0.5).
BOARD_VIEWS = 5


@pytest.fixture(scope="module")
def board_5mp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("board_5mp")
    spec = SessionSpec(width=1228, height=1029, views=BOARD_VIEWS, k1=-0.1, seed=31, size_range=(0.5, 0.8),
                       empty_views=1)
    render_session(resolve_target("pascal_board_a3"), spec, out)
    truth = _truth(out)
    for name in truth["images"]:
        img = cv2.imread(str(out / name), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(out / name), cv2.resize(img, (2456, 2058), interpolation=cv2.INTER_CUBIC))
    K = np.array(truth["K"])
    K[:2] *= 2.0
    K[:2, 2] += 0.5
    truth.update(K=K.tolist(), size=ImageSize(2456, 2058))
    (out / "session.json").write_text(json.dumps(truth, indent=1))
    return out


def _idle(kv: dict[str, str]) -> bool:
    """The detector has finished with every frame the node received (none pending or running)."""
    n = int(kv.get("frames_received", 0))
    return n > 0 and int(kv["frames_examined"]) + int(kv["frames_dropped"]) == n











def _run_session(tmp_path: Path, source: Path, calib_params: dict, replay_params: dict, truth: dict,
                 call: bool = True) -> None:
    """Start both nodes, wait for ready, calibrate, check the CameraInfo; stop cleanly."""
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"min_views": 6, "calibration_file": str(tmp_path / "cam.yaml"),
                                           **calib_params}, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(source), "rate": 8.0, "wait_for_subscribers": 1,
                                      "exit_when_done": True, **replay_params}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: latest_status(status).get("ready") == "True", 60), (
            f"{latest_status(status)}\n{cal.log()}{rep.log()}")
        if call:
            resp = client.call_trigger("/pascal_calib/calibrate")
            assert resp.success, resp.message
        got = camera_info_subscription(client)  # subscribed after the result: transient local delivers it
        assert client.spin_until(lambda: bool(got), 60), cal.log()
        _check_k(got[-1].k, truth)
        assert got[-1].distortion_model == "plumb_bob" and len(got[-1].d) == 5
        assert (tmp_path / "cam.yaml").exists()
        assert rep.wait(30) == 0
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()
        rep.stop()


def test_folder_session_calibrate_commit_reset(tmp_path: Path, session: Path) -> None:
    from sensor_msgs.srv import SetCameraInfo

    dom = next_domain_id()
    params = {"min_views": 6, "output_dir": str(tmp_path / "out"), "camera_name": "e2e_cam",
              "set_camera_info_service": "/camera/set_camera_info", "cross_validate": True}
    cal = NodeProcess("calibration_node", params, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    rep = None
    try:
        status = status_subscription(client)
        info = camera_info_subscription(client)
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "no calibration to commit" in r.message
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "0 view(s) collected; need 6" in r.message
        rep = NodeProcess("replay_node", {"source": str(session), "rate": 8.0, "wait_for_subscribers": 1},
                          dom, tmp_path / "rep.log")
        assert client.spin_until(lambda: latest_status(status).get("ready") == "True", 60), cal.log()
        st = latest_status(status)
        assert int(st["views_accepted"]) >= 6 and float(st["coverage_skew"]) > 0
        assert not info  # nothing published before a calibration
        r = client.call_trigger("/pascal_calib/calibrate")
        assert r.success, r.message
        assert "fx=" in r.message and "rms=" in r.message and "views=" in r.message
        assert "projection sigma" in r.message
        # at most 10 views for two halves of min_views 6: said in the answer, the calibration stands
        assert "cross-validation not possible" in r.message and "needs 12" in r.message, r.message
        assert client.spin_until(lambda: bool(info), 10)
        _check_k(info[-1].k, _truth(session))
        doc = yaml.safe_load((tmp_path / "out" / "e2e_cam.yaml").read_text())
        assert doc["camera_name"] == "e2e_cam"
        # every stored view was written as it was taken into the session folder ~/status names
        folder = Path(latest_status(status)["session_folder"])
        assert folder.parent == tmp_path / "out" / "sessions", latest_status(status)
        frames = {f.stem for f in (folder / "frames").glob("*.png")}
        assert len(frames) >= 6 and len(yaml.safe_load((folder / "session.yaml").read_text())["views"]) == len(frames)
        # one result set, labelled: the answer and ~/status name it; the files are links through current
        rid = r.message.split("result=")[1].split()[0]
        assert (tmp_path / "out" / "results" / rid / "e2e_cam.yaml").is_file(), r.message
        assert client.spin_until(lambda: latest_status(status).get("result_id") == rid, 10), latest_status(status)
        assert (tmp_path / "out" / "e2e_cam.yaml").resolve() == (tmp_path / "out" / "results" / rid / "e2e_cam.yaml")
        # the report of the calibration, its worst views read back from the stored frames by name
        assert (tmp_path / "out" / "report.pdf").stat().st_size > 10_000
        report = json.loads((tmp_path / "out" / "report.json").read_text())
        assert report["residuals"]["worst_views"] and set(report["residuals"]["worst_views"]) <= frames
        assert report["residuals"]["model_bias"]["detected"] is False
        assert (tmp_path / "out" / "e2e_cam.calibration.json").exists()  # the covariance ~/verify and export use
        # ~/verify: the views of the session against its own result hold
        r = client.call_trigger("/pascal_calib/verify", timeout=120.0)
        assert r.success and r.message.startswith("verdict: HOLDS") and "projection shift" in r.message, r.message
        assert client.spin_until(lambda: latest_status(status).get("verify", "").startswith("verdict: HOLDS"), 10)
        # ~/commit: driver missing, then accepting, then refusing
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "not available" in r.message
        received: list = []
        accept = [True]

        def serve(req: SetCameraInfo.Request, resp: SetCameraInfo.Response) -> SetCameraInfo.Response:
            received.append(req.camera_info)
            resp.success, resp.status_message = accept[0], "stored" if accept[0] else "read-only camera"
            return resp

        client.node.create_service(SetCameraInfo, "/camera/set_camera_info", serve)
        r = client.call_trigger("/pascal_calib/commit")
        assert r.success and "stored" in r.message and f"result {rid}" in r.message, r.message
        assert np.allclose(received[-1].k, info[-1].k)
        accept[0] = False
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "read-only camera" in r.message
        r = client.call_trigger("/pascal_calib/reset")
        assert r.success and "cleared" in r.message
        assert client.spin_until(lambda: latest_status(status).get("views_accepted") == "0", 5)
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success  # too few views again, and the last good result stays published
        # a stale result is not committed as if it were new; ~/status says the last attempt failed
        accept[0] = True
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "failed" in r.message and f"result {rid}" in r.message and "is older" in r.message
        assert client.spin_until(lambda: latest_status(status).get("last_attempt", "").startswith("failed"), 5)
        r = client.call_trigger("/pascal_calib/verify")
        assert not r.success and "cannot test" in r.message, r.message
        late = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(late), 10)
        assert np.allclose(late[-1].k, info[-1].k)
    finally:
        client.close()
        if rep is not None:
            rep.stop()
        assert cal.stop(signal.SIGTERM) == 0, cal.log()


def test_sqlite3_bag(tmp_path: Path, session: Path) -> None:
    bag = write_image_bag(tmp_path / "bag", sorted(session.glob("*.png")), "/cam/image_raw", "sqlite3")
    _run_session(tmp_path, bag, {}, {"topic": "image"}, _truth(session))


def test_mcap_bag_compressed_transport(tmp_path: Path, session: Path) -> None:
    bag = write_image_bag(tmp_path / "bag", sorted(session.glob("*.png")), "/cam/image", "mcap", compressed=True)
    _run_session(tmp_path, bag, {"transport": "compressed"}, {"mode": "timed", "rate": 0.0}, _truth(session))
    assert "on /image/compressed (reliable); timed: recorded timing" in (tmp_path / "rep.log").read_text()


def test_best_effort_publisher_with_auto_qos(tmp_path: Path, session: Path) -> None:
    _run_session(tmp_path, session, {"qos": "auto"}, {"qos": "best_effort", "rate": 4.0}, _truth(session))


def test_folder_compressed_transport(tmp_path: Path, session: Path) -> None:
    # a topic already ending in /compressed is used as is (not .../compressed/compressed)
    _run_session(tmp_path, session, {"transport": "compressed", "auto_calibrate": True},
                 {"transport": "compressed", "topic": "/image/compressed"}, _truth(session), call=False)
    log = (tmp_path / "rep.log").read_text()
    assert "as sensor_msgs/CompressedImage on /image/compressed (reliable); lock-step" in log, log


def test_invalid_parameters_refuse_to_start(tmp_path: Path) -> None:
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"qos": "sometimes"}, dom, tmp_path / "cal.log")
    assert cal.wait(30) == 2
    assert "qos='sometimes' is not one of" in cal.log()
    rep = NodeProcess("replay_node", {"source": str(tmp_path / "missing")}, dom, tmp_path / "rep.log")
    assert rep.wait(30) == 2
    assert "no image files" in rep.log()


@contextmanager
def _replayed(tmp_path: Path, imgs: Path, cal_params: dict, min_accepted: int) -> Iterator[tuple[RosClient, Any]]:
    """The calibration node fed the folder ``imgs`` by the replay node until it has stored at least
    ``min_accepted`` views; the client and the node's process, stopped (cleanly) afterwards."""
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", cal_params, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(imgs), "rate": 5.0, "wait_for_subscribers": 1,
                                      "exit_when_done": True}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: rep.proc.poll() is not None, 60), rep.log()
        assert client.spin_until(lambda: int(latest_status(status).get("views_accepted", 0)) >= min_accepted, 10), \
            (str(latest_status(status)), cal.log())
        yield client, cal
    finally:
        client.close()
        rep.stop()
        assert cal.stop() == 0, cal.log()


def test_grid_target_with_estimated_shape(tmp_path: Path) -> None:
    """A ring grid printed on a bent sheet: the node collects grid views, calibrates with the
    estimated warp and writes it to report.json; a ring target with a shape is refused."""
    imgs = tmp_path / "imgs"
    spec = SessionSpec(width=800, height=600, focal=600, views=10, k1=-0.2, seed=5, size_range=(0.5, 0.85),
                       warp_x=0.001)
    render_session(resolve_target("ring_grid_a4"), spec, imgs)
    out = tmp_path / "out"
    with _replayed(tmp_path, imgs, {"target": "ring_grid_a4", "target_shape": "warp", "min_views": 6,
                                    "min_view_distance": 0.01, "output_dir": str(out)}, 8) as (client, cal):
        r = client.call_trigger("/pascal_calib/calibrate")
        assert r.success, r.message
        assert "method=grid" in r.message and "target shape matters" in r.message
        got = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(got), 10), cal.log()
        _check_k(got[-1].k, _truth(imgs))
        doc = json.loads((out / "report.json").read_text())
        assert abs(doc["target_shape"]["estimated"]["warp_x"] - 0.001) < 1e-4, doc["target_shape"]
    bad = NodeProcess("calibration_node", {"target": "ring_a4", "target_shape": "warp"}, next_domain_id(),
                      tmp_path / "bad.log")
    assert bad.wait(30) == 2
    assert "target_shape needs a grid or checkerboard target" in bad.log()


def test_output_topic_of_replay() -> None:
    assert output_topic("image", False) == ("image", "")
    assert output_topic("image", True) == ("image/compressed", "")
    assert output_topic("/cam/image/compressed", True) == ("/cam/image/compressed", "")  # not appended twice
    assert output_topic("/cam/image/", True) == ("/cam/image/compressed", "")
    topic, warning = output_topic("/cam/image/compressed", False)
    assert topic == "/cam/image/compressed" and "raw sensor_msgs/Image" in warning


def test_5mp_board_session_in_lockstep_uses_every_frame(tmp_path: Path, board_5mp: Path) -> None:
    """A 5 MP board session replayed at full speed (lock-step, the default): whatever the
    detector's speed, every frame is examined, none dropped, every view with the board is
    collected and the calibration succeeds."""
    truth = _truth(board_5mp)
    n_frames = len(truth["images"])  # BOARD_VIEWS with the board + 1 empty
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"target": "pascal_board_a3", "method": "ring", "min_views": BOARD_VIEWS,
                                           "min_view_distance": 0.0, "calibration_file": str(tmp_path / "c.yaml")},
                      dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(board_5mp), "exit_when_done": True}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    t0 = time.monotonic()
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: rep.proc.poll() is not None, 150), f"{latest_status(status)}\n{rep.log()}"
        assert rep.wait(1) == 0, rep.log()
        assert client.spin_until(lambda: latest_status(status).get("frames_examined") == str(n_frames), 5)
        kv = latest_status(status)
        assert kv["frames_received"] == str(n_frames) and kv["frames_dropped"] == "0", kv
        assert kv["views_accepted"] == str(BOARD_VIEWS) and kv["views_rejected"] == "1", kv
        assert not kv["frames_dropped_note"], kv
        log = rep.log()
        assert "lock-step" in log and f"replay finished: {n_frames} message(s) on /image, {n_frames} examined" in log
        r = client.call_trigger("/pascal_calib/calibrate")
        assert r.success, r.message
        assert "method=ring" in r.message and f"views={BOARD_VIEWS}/{BOARD_VIEWS}" in r.message, r.message
        got = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(got), 10), cal.log()
        _check_k(got[-1].k, truth, rel=5e-3, pp_px=8.0)
        print(f"5 MP lock-step session: {n_frames} frames, {time.monotonic() - t0:.1f} s")
    finally:
        client.close()
        rep.stop()
        assert cal.stop() == 0, cal.log()


def test_timed_replay_too_fast_reports_dropped_frames(tmp_path: Path, board_5mp: Path) -> None:
    """The same session looped in timed mode far faster than the node: frames are dropped, and
    ~/calibrate and ~/status say so and what to do instead of blaming the motion. The files'
    bytes are sent as they are (compressed transport): the replay only reads files while the node
    decodes 5 MP PNGs and detects, so it outruns the node however fast the detector becomes."""
    dom = next_domain_id()
    # min_views above the session's distinct views: the looped views never make it ready
    cal = NodeProcess("calibration_node", {"target": "pascal_board_a3", "method": "ring", "min_views": BOARD_VIEWS + 3,
                                           "transport": "compressed"}, dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(board_5mp), "mode": "timed", "rate": 100.0, "loop": True,
                                      "transport": "compressed", "wait_for_subscribers": 1}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: int(latest_status(status).get("frames_received", 0)) >= 20, 60), (
            f"{latest_status(status)}\n{rep.log()}")
        rep.stop()
        assert "timed: 100 Hz" in rep.log()
        assert client.spin_until(lambda: _idle(latest_status(status)), 60), f"{latest_status(status)}\n{cal.log()}"
        client.spin_until(lambda: False, 1.1)  # a status of the idle node
        kv = latest_status(status)
        dropped = int(kv["frames_dropped"])
        assert dropped >= 1 and kv["frames_dropped_session"] == str(dropped), kv
        assert f"{dropped} frame(s) dropped while the detector was busy" in status[-1].status[0].message
        assert "lock-step" in kv["frames_dropped_note"], kv
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success
        assert f"{dropped} of {kv['frames_received']} frame(s) arrived while the detector was busy" in r.message
        assert "mode:=lockstep" in r.message and "Move the target" not in r.message, r.message
        # after ~/reset the new session has dropped nothing yet: the refusal is the usual one
        assert client.call_trigger("/pascal_calib/reset").success
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success and "0 view(s) collected" in r.message and "dropped" not in r.message, r.message
    finally:
        client.close()
        rep.stop()
        assert cal.stop() == 0, cal.log()


def test_lockstep_without_calibration_node_stops_with_an_error(tmp_path: Path, session: Path) -> None:
    dom = next_domain_id()
    rep = NodeProcess("replay_node", {"source": str(session), "ack_timeout": 2.0, "exit_when_done": True},
                      dom, tmp_path / "rep.log")
    assert rep.wait(30) == 1, rep.log()
    assert "lock-step: no calibration node within 2 s" in rep.log() and "mode:=timed" in rep.log()
    bad = NodeProcess("replay_node", {"source": str(session), "mode": "fast"}, dom, tmp_path / "bad.log")
    assert bad.wait(30) == 2
    assert "mode must be lockstep or timed" in bad.log()


def test_lockstep_replay_started_before_the_node(tmp_path: Path, session: Path) -> None:
    """Lock-step waits for a calibration node that starts later, and loses no frame to the
    discovery race (the acknowledgements are transient local)."""
    n_frames = len(_truth(session)["images"])
    dom = next_domain_id()
    rep = NodeProcess("replay_node", {"source": str(session), "exit_when_done": True}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    cal = None
    try:
        client.spin_until(lambda: False, 3.0)
        assert rep.proc.poll() is None, rep.log()
        cal = NodeProcess("calibration_node", {"min_views": 6}, dom, tmp_path / "cal.log")
        status = status_subscription(client)
        assert client.spin_until(lambda: rep.proc.poll() is not None, 60), rep.log()
        assert rep.wait(1) == 0, rep.log()
        assert client.spin_until(lambda: latest_status(status).get("frames_examined") == str(n_frames), 5), (
            f"{latest_status(status)}\n{rep.log()}")
        kv = latest_status(status)
        assert kv["frames_received"] == str(n_frames) and kv["frames_dropped"] == "0", kv
        assert f"{n_frames} examined by the calibration node" in rep.log()
    finally:
        client.close()
        rep.stop()
        if cal is not None:
            assert cal.stop() == 0, cal.log()


def _bgr(msg: Any) -> np.ndarray:
    """A bgr8 sensor_msgs/Image as an (H, W, 3) array."""
    assert msg.encoding == "bgr8"
    return np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.step)[:, :msg.width * 3].reshape(
        msg.height, msg.width, 3)


def test_detections_show_footprints_coverage_bars_and_state(tmp_path: Path, session: Path) -> None:
    """~/detections is the session's whole GUI: the last frame's picture is the one the overlay
    draws for the same frames (the stored views' footprints, the coverage bars, the view count and
    the frame's verdict), and its bars agree with the coverage ~/status reports."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    from pascal_calib_ros.detect.detection import DetectionParams, feature_points
    from pascal_calib_ros.detect.target_detector import detect_target
    from pascal_calib_ros.geometry.image_field import view_hulls
    from pascal_calib_ros.io.images import IMAGE_SUFFIXES, read_grey
    from pascal_calib_ros.session.collector import AXES, ViewCollector
    from pascal_calib_ros.session.overlay import (
        BAR_EMPTY_BGR,
        BAR_FULL_BGR,
        bar_rects,
        draw_live_overlay,
        panel_width,
    )

    min_views = 6
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"min_views": min_views}, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    rep = None
    try:
        status = status_subscription(client)
        pictures: list = []
        client.node.create_subscription(Image, "/pascal_calib/detections", pictures.append, 10)
        examined: list = []
        qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        client.node.create_subscription(Header, "/pascal_calib/examined_frames", examined.append, qos)
        assert client.spin_until(lambda: client.node.count_publishers("/pascal_calib/detections") > 0, 20), cal.log()
        rep = NodeProcess("replay_node", {"source": str(session), "wait_for_subscribers": 1, "exit_when_done": True},
                          dom, tmp_path / "rep.log")
        assert client.spin_until(lambda: rep.proc.poll() is not None, 60), rep.log()
        assert rep.wait(1) == 0, rep.log()

        def last_picture_arrived() -> bool:
            return bool(examined and pictures and pictures[-1].header.stamp == examined[-1].stamp)

        assert client.spin_until(last_picture_arrived, 10), cal.log()
        client.spin_until(lambda: False, 1.1)  # a status after the last frame
        got = _bgr(pictures[-1])
        kv = latest_status(status)
    finally:
        client.close()
        if rep is not None:
            rep.stop()
        assert cal.stop() == 0, cal.log()

    # the same frames through the same detector and collector: the picture the node should draw
    files = sorted(p for p in session.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    collector = ViewCollector(min_views)
    footprints: list[np.ndarray] = []
    for f in files:
        img = read_grey(f)
        det = detect_target(img, resolve_target("ring_a4"), DetectionParams.for_lens(False))
        if det.ok:
            accepted, why = collector.offer(det)
            verdict = f"view {len(collector.views) - 1} stored" if accepted else f"ok; not stored: {why}"
            if accepted:
                footprints += view_hulls([feature_points(det)])
        else:
            verdict = det.reason
    h, w = img.shape
    assert got.shape == (h, w + panel_width(h), 3)
    assert kv["views_accepted"] == str(len(collector.views)) and len(footprints) == len(collector.views) >= min_views
    want = draw_live_overlay(img, det, footprints, collector.coverage(), len(collector.views), min_views,
                             collector.ready, verdict, verdict_ok=det.ok)
    differ = np.any(got != want, axis=2)
    assert differ.mean() < 1e-3, f"{differ.sum()} pixels differ"  # subpixel edges may round differently
    # inside each footprint the frame is tinted (magenta: blue and red above green)
    for hull in footprints:
        x, y = np.round(hull.mean(0)).astype(int)
        b, g, r = got[y, x].astype(int)
        assert b > g and r > g, (x, y, got[y, x])
    # the bars show what ~/status reports
    for axis, (x0, y0, x1, y1) in bar_rects(ImageSize(w, h)).items():
        c = float(kv[f"coverage_{axis}"])
        ym = (y0 + y1) // 2
        if c >= 1.0:
            assert np.all(got[y0:y1, x0:x1] == BAR_FULL_BGR), axis
        else:
            assert abs(int(got[ym, x0 + round(c * (x1 - x0) / 2), 1]) - 255 * c) <= 2, (axis, c)
            if c < 0.95:
                assert np.array_equal(got[ym, x1 - 2], BAR_EMPTY_BGR), axis
    assert {f"coverage_{a}" for a in AXES} <= set(kv)


def test_charuco_board_from_its_own_yaml_with_partial_views(tmp_path: Path) -> None:
    """A user's ChArUco described in a YAML file (``-p target:=board.yaml``): whole and partial
    views are collected and calibrated; the CameraInfo close to the truth."""
    board = tmp_path / "board.yaml"
    board.write_text((Path(__file__).parents[2] / "config" / "targets" / "charuco_a3.yaml").read_text()
                     .replace("name: charuco_a3", "name: my_board"))
    imgs = tmp_path / "imgs"
    spec = SessionSpec(width=800, height=600, views=8, partial_views=4, k1=-0.2, seed=3, size_range=(0.5, 0.8))
    render_session(resolve_target(str(board)), spec, imgs)
    with _replayed(tmp_path, imgs, {"target": str(board), "min_views": 6, "min_view_distance": 0.01}, 9) as (client,
                                                                                                              cal):
        r = client.call_trigger("/pascal_calib/calibrate")
        assert r.success, r.message
        assert "method=zhang" in r.message
        got = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(got), 10), cal.log()
        _check_k(got[-1].k, _truth(imgs), rel=5e-4, pp_px=1.0)
