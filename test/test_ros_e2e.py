"""Real nodes as separate processes over real DDS (Fast DDS), in a private network namespace:
replay -> calibration node -> ~/calibrate from this test -> CameraInfo checked against the
renderer's ground truth."""

from __future__ import annotations

import json
import signal
from pathlib import Path

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

from pascal_calib_ros.io.bags import write_image_bag
from pascal_calib_ros.sim.session import SessionSpec, render_session
from pascal_calib_ros.targets import resolve_target

pytestmark = require_netns


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ros_session")
    spec = SessionSpec(width=640, height=480, views=10, k1=-0.2, seed=21, empty_views=1)
    render_session(resolve_target("ring_a4"), spec, out)
    return out


def _truth(session: Path) -> dict:
    return json.loads((session / "session.json").read_text())


def _check_k(k: list[float] | np.ndarray, truth: dict) -> None:
    K = np.asarray(k, float).reshape(3, 3)
    Kt = np.array(truth["K"])
    assert abs(K[0, 0] / Kt[0, 0] - 1) < 1e-3 and abs(K[1, 1] / Kt[1, 1] - 1) < 1e-3, K
    assert np.hypot(K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]) < 1.5, K











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
              "set_camera_info_service": "/camera/set_camera_info"}
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
        assert client.spin_until(lambda: bool(info), 10)
        _check_k(info[-1].k, _truth(session))
        doc = yaml.safe_load((tmp_path / "out" / "e2e_cam.yaml").read_text())
        assert doc["camera_name"] == "e2e_cam"
        assert len(list((tmp_path / "out" / "frames").glob("*.png"))) >= 6
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
        assert r.success and "stored" in r.message
        assert np.allclose(received[-1].k, info[-1].k)
        accept[0] = False
        r = client.call_trigger("/pascal_calib/commit")
        assert not r.success and "read-only camera" in r.message
        r = client.call_trigger("/pascal_calib/reset")
        assert r.success and "cleared" in r.message
        assert client.spin_until(lambda: latest_status(status).get("views_accepted") == "0", 5)
        r = client.call_trigger("/pascal_calib/calibrate")
        assert not r.success  # too few views again, and the last good result stays published
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
    _run_session(tmp_path, bag, {"transport": "compressed"}, {"rate": 0.0}, _truth(session))


def test_best_effort_publisher_with_auto_qos(tmp_path: Path, session: Path) -> None:
    _run_session(tmp_path, session, {"qos": "auto"}, {"qos": "best_effort", "rate": 4.0}, _truth(session))


def test_folder_compressed_transport(tmp_path: Path, session: Path) -> None:
    _run_session(tmp_path, session, {"transport": "compressed", "auto_calibrate": True},
                 {"transport": "compressed"}, _truth(session), call=False)


def test_invalid_parameters_refuse_to_start(tmp_path: Path) -> None:
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"qos": "sometimes"}, dom, tmp_path / "cal.log")
    assert cal.wait(30) == 2
    assert "qos='sometimes' is not one of" in cal.log()
    rep = NodeProcess("replay_node", {"source": str(tmp_path / "missing")}, dom, tmp_path / "rep.log")
    assert rep.wait(30) == 2
    assert "no image files" in rep.log()


def test_grid_target_with_estimated_shape(tmp_path: Path) -> None:
    """A ring grid printed on a bent sheet: the node collects grid views, calibrates with the
    estimated warp and writes it to calibration.json; a ring target with a shape is refused."""
    imgs = tmp_path / "imgs"
    spec = SessionSpec(width=800, height=600, focal=600, views=10, k1=-0.2, seed=5, size_range=(0.5, 0.85),
                       warp_x=0.001)
    render_session(resolve_target("ring_grid_a4"), spec, imgs)
    dom = next_domain_id()
    out = tmp_path / "out"
    cal = NodeProcess("calibration_node", {"target": "ring_grid_a4", "target_shape": "warp", "min_views": 6,
                                           "min_view_distance": 0.01, "output_dir": str(out)},
                      dom, tmp_path / "cal.log")
    rep = NodeProcess("replay_node", {"source": str(imgs), "rate": 5.0, "wait_for_subscribers": 1,
                                      "exit_when_done": True}, dom, tmp_path / "rep.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: rep.proc.poll() is not None, 60), rep.log()
        assert client.spin_until(lambda: int(latest_status(status).get("views_accepted", 0)) >= 8, 10), cal.log()
        r = client.call_trigger("/pascal_calib/calibrate")
        assert r.success, r.message
        assert "method=grid" in r.message and "target shape matters" in r.message
        got = camera_info_subscription(client)
        assert client.spin_until(lambda: bool(got), 10), cal.log()
        _check_k(got[-1].k, _truth(imgs))
        doc = json.loads((out / "calibration.json").read_text())
        assert abs(doc["target_shape"]["warp_x"] - 0.001) < 1e-4, doc["target_shape"]
    finally:
        client.close()
        rep.stop()
        assert cal.stop() == 0, cal.log()
    bad = NodeProcess("calibration_node", {"target": "ring_a4", "target_shape": "warp"}, dom, tmp_path / "bad.log")
    assert bad.wait(30) == 2
    assert "target_shape needs a grid or checkerboard target" in bad.log()
