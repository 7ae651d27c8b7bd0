"""A stereo session nothing loses, through the real node over DDS: each stored shot written into
its session folder as it is taken, the node killed with SIGKILL, started again with
``resume:=true``: the same shots, and the same calibration as before the kill and as
``pascal-calib stereo SESSION`` computes offline; a folder with shots is never overwritten and one
recorded with other settings is refused with the differences; a shot that cannot be written is
said, counted and kept."""

from __future__ import annotations

import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_harness import NodeProcess, RosClient, latest_status, next_domain_id, require_netns, status_subscription

from pascal_calib_ros.cli import main as cli_main
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.session_folder import SessionFolder
from pascal_calib_ros.io.stereo_yaml import read_stereo_yaml
from pascal_calib_ros.sim.rig import RigSpec, render_rig, stereo_pair
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]

GRID = "ring_grid_a4"
SHOTS = 6  # 4 before the kill, 2 after the resume
NODE = {"mode": "stereo", "target": GRID, "gamma": 2.2, "min_views": 3, "min_view_distance": 0.0,
        "camera_name": "head"}


@pytest.fixture(scope="module")
def shots() -> list[list[np.ndarray]]:
    """Small frames (480x360) of a rendered pair, [shot][camera]."""
    rig = render_rig(resolve_target(GRID), RigSpec(stereo_pair(480, 360), shots=SHOTS, single_shots=0, seed=1))
    return [[rig.images[c][k] for c in (0, 1)] for k in range(SHOTS)]


def _image(img: np.ndarray, stamp_ns: int, frame_id: str) -> Any:
    from sensor_msgs.msg import Image

    from pascal_calib_ros.io.image_msgs import grey_to_image_fields

    msg = Image(**grey_to_image_fields(img))
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_ns // 10**9, stamp_ns % 10**9
    msg.header.frame_id = frame_id
    return msg


def _result(out: Path) -> dict[str, Any]:
    """The node's published pair, read from its output folder."""
    cams = {side: read_camera_yaml(out / f"{side}.yaml") for side in ("left", "right")}
    return {"cams": cams, "rig": read_stereo_yaml(out / "stereo.yaml")["rig"]}


def _same(a: dict[str, Any], b: dict[str, Any], tol: float) -> None:
    for side in ("left", "right"):
        ca, cb = a["cams"][side], b["cams"][side]
        np.testing.assert_allclose(ca.K, cb.K, rtol=tol, atol=tol)
        np.testing.assert_allclose(ca.D, cb.D, rtol=0, atol=tol)
        np.testing.assert_allclose(ca.R, cb.R, rtol=0, atol=tol)
        np.testing.assert_allclose(ca.projection, cb.projection, rtol=tol, atol=tol)
    np.testing.assert_allclose(a["rig"].matrix, b["rig"].matrix, rtol=0, atol=tol)


def test_a_killed_stereo_session_resumes_with_the_same_shots_and_result(
        tmp_path: Path, shots: list[list[np.ndarray]]) -> None:
    from sensor_msgs.msg import Image

    session, out = tmp_path / "session", tmp_path / "out"
    params = {**NODE, "session_dir": str(session), "output_dir": str(out)}
    dom = next_domain_id()
    client = RosClient(dom)
    first = NodeProcess("calibration_node", params, dom, tmp_path / "a.log")
    second = None
    try:
        status = status_subscription(client)
        pubs = [client.node.create_publisher(Image, f"/{side}/image", 5) for side in ("left", "right")]
        t0 = time.time_ns()

        def send(k: int, stored: int, node: NodeProcess) -> None:
            assert client.spin_until(lambda: all(p.get_subscription_count() for p in pubs), 30), node.log()
            for c, p in enumerate(pubs):
                p.publish(_image(shots[k][c], t0 + k * 10**9, "lr"[c]))
            assert client.spin_until(lambda: latest_status(status).get("shots_both") == str(stored), 30), node.log()

        assert client.spin_until(lambda: latest_status(status).get("session_folder") == str(session), 30), first.log()
        for k in range(4):
            send(k, k + 1, first)
        r = client.call_trigger("/pascal_calib/calibrate", timeout=120.0)
        assert r.success and "shots=4 both/4" in r.message, r.message + first.log()
        before = _result(out)
        first.proc.send_signal(signal.SIGKILL)
        first.proc.wait(10)
        recorded = SessionFolder.open(session)
        assert recorded.manifest.cameras == ("left", "right") and recorded.manifest.image_size == (480, 360)
        assert [v.name for v in recorded.views] == [f"shot_{k:06d}" for k in range(4)]
        for k, v in enumerate(recorded.views):  # both frames, lossless, with their stamps
            assert v.stamps_ns == (t0 + k * 10**9,) * 2 and v.not_used == ("", "")
            assert all(np.array_equal(recorded.image(v, c), shots[k][c]) for c in (0, 1))
        # without resume the folder is never overwritten; recorded with another gamma it is refused
        refused = NodeProcess("calibration_node", params, dom, tmp_path / "b.log")
        assert refused.proc.wait(30) == 2, refused.log()
        assert "already holds a session with views: continue it (resume)" in refused.log(), refused.log()
        other = NodeProcess("calibration_node", {**params, "resume": True, "gamma": 1.0}, dom, tmp_path / "c.log")
        assert other.proc.wait(60) == 2, other.log()
        assert "recorded with other settings (gamma: 2.2 != 1.0)" in other.log(), other.log()
        assert len(SessionFolder.open(session).views) == 4
        status.clear()
        second = NodeProcess("calibration_node", {**params, "resume": True}, dom, tmp_path / "d.log")
        assert client.spin_until(lambda: latest_status(status).get("shots_both") == "4", 60), second.log()
        assert "4 shot(s) resumed" in second.log()
        r = client.call_trigger("/pascal_calib/calibrate", timeout=120.0)
        assert r.success and "shots=4 both/4" in r.message, r.message + second.log()
        after = _result(out)
        _same(before, after, 1e-9)
        # offline, from the folder alone: the same calibration
        assert cli_main(["stereo", str(session), "-o", str(tmp_path / "offline")]) == 0
        offline = _result(tmp_path / "offline")
        _same(after, offline, 1e-9)
        assert offline["cams"]["left"].camera_name == "head/left"
        # the single-camera command refuses a pair's folder (it would calibrate the left frames alone)
        assert cli_main(["calibrate", str(session), "-o", str(tmp_path / "mono.yaml")]) != 0
        assert not (tmp_path / "mono.yaml").exists()
        # the session goes on, new shots numbered after the resumed ones; a frame that cannot be
        # written (a folder where its file goes) is said and counted, the shot kept in memory
        (session / "frames" / "left" / "shot_000004.png").mkdir()
        send(4, 5, second)
        assert client.spin_until(lambda: latest_status(status).get("session_views_not_written") == "1", 10)
        st = latest_status(status)
        assert st["last_error"].startswith("not written to the session folder: cannot write") and \
            "shot_000004.png" in st["last_error"], st
        assert "shot 4 stored (both cameras); not written to the session folder" in second.log()
        send(5, 6, second)
        names = [v.name for v in SessionFolder.open(session).views]
        assert names == [f"shot_{k:06d}" for k in (0, 1, 2, 3, 5)], names
        assert client.spin_until(lambda: latest_status(status).get("session_views_written") == "5", 10)
    finally:
        client.close()
        if second is not None:
            assert second.stop() == 0, second.log()
