"""The ``publisher`` node over DDS (separate processes, private network namespace): a saved
``hand_eye.yaml`` broadcast on /tf_static and received by tf2 listeners started afterwards in their own
processes, equal to the file to 1e-9; a changed file broadcast again without a restart; a file it cannot
stand behind refused with the reason (at start: exit code 2; later: the previous transform stays)."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros_harness import NodeProcess, next_domain_id, require_netns, tf_static_echo

from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.hand_eye_yaml import HandEyeRecord, write_hand_eye_yaml

pytestmark = [require_netns, pytest.mark.ros]

RECORD = HandEyeRecord("eye_to_hand", "base_link", "camera_optical_frame",
                       Transform.from_rotvec([0.4, -1.2, 0.3], [0.812345678912, -0.2, 1.1]), (0.2, 0.3, 0.25),
                       (0.01, 0.02, 0.015), "tool0", Transform.from_rotvec([0, 0, 0.5], [0.0, 0.0, 0.1]), 12, 0.08)


def _wait_for(proc: NodeProcess, text: str, count: int = 1, timeout: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.log().count(text) >= count:
            return True
        if proc.proc.poll() is not None:
            return False
        time.sleep(0.1)
    return False


def _assert_same(sent: dict, path: Path) -> None:
    doc = yaml.safe_load(path.read_text())
    assert (sent["parent"], sent["child"]) == (doc["parent_frame"], doc["child_frame"])
    np.testing.assert_allclose(sent["translation"], doc["translation"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sent["rotation"], doc["rotation"], rtol=0, atol=1e-9)


def test_saved_hand_eye_is_broadcast_and_follows_the_file(tmp_path: Path) -> None:
    path = write_hand_eye_yaml(tmp_path / "hand_eye.yaml", RECORD)
    dom = next_domain_id()
    pub = NodeProcess("publisher", {"file": str(path), "watch_period": 0.2}, dom, tmp_path / "pub.log")
    try:
        assert _wait_for(pub, "broadcasting hand_eye eye_to_hand: base_link -> camera_optical_frame"), pub.log()
        got = tf_static_echo(dom, ["camera_optical_frame"])  # started after the broadcast
        assert got["rc"] == 0 and got["publishers"] == 1, got["output"] + pub.log()
        _assert_same(got["by_child"]["camera_optical_frame"], path)
        # a recalibration: the new file is broadcast without a restart
        moved = replace(RECORD, X=Transform.from_rotvec([0.41, -1.2, 0.3], [0.8, -0.25, 1.1]))
        write_hand_eye_yaml(path, moved)
        assert _wait_for(pub, "the file changed: broadcasting"), pub.log()
        got = tf_static_echo(dom, ["camera_optical_frame"])
        assert got["rc"] == 0 and len(got["transforms"]) == 1, got["output"]
        _assert_same(got["by_child"]["camera_optical_frame"], path)
        kept = path.read_text()
        # a result the node would not have published: refused, the previous transform stays
        write_hand_eye_yaml(path, replace(moved, translation_std_mm=(0.2, 7.5, 0.2)))
        assert _wait_for(pub, "refused: "), pub.log()
        assert "translation std up to 7.50 mm (> 5 mm); still broadcasting the previous transform" in pub.log()
        got = tf_static_echo(dom, ["camera_optical_frame"])
        (tmp_path / "kept.yaml").write_text(kept)
        _assert_same(got["by_child"]["camera_optical_frame"], tmp_path / "kept.yaml")
        # other frames: refused (a static transform cannot be withdrawn), with what to do
        write_hand_eye_yaml(path, replace(moved, child_frame="other_camera"))
        assert _wait_for(pub, "restart the publisher to broadcast the new frames"), pub.log()
        assert pub.proc.poll() is None, pub.log()
    finally:
        assert pub.stop() == 0, pub.log()


@pytest.mark.parametrize(("write", "why"), [
    (lambda p: write_hand_eye_yaml(p, replace(RECORD, rotation_std_deg=(0.9, 0.0, 0.0))),
     "rotation std up to 0.900 deg (> 0.5 deg)"),
    (lambda p: p.write_text("R: [1, 2]\n"), "neither a hand-eye result"),
    (lambda p: None, "cannot read"),
])
def test_a_file_it_cannot_stand_behind_stops_it_at_start(tmp_path: Path, write: object, why: str) -> None:
    path = tmp_path / "hand_eye.yaml"
    write(path)  # type: ignore[operator]
    pub = NodeProcess("publisher", {"file": str(path)}, next_domain_id(), tmp_path / "pub.log")
    try:
        assert pub.wait(30) == 2, pub.log()
        assert why in pub.log() and str(path) in pub.log(), pub.log()
    finally:
        pub.stop()


def test_a_rig_is_broadcast_whole(tmp_path: Path) -> None:
    """A rig.yaml (``pascal-calib rig``): every camera's transform from the reference camera, received
    by a late listener in another process."""
    from rig_sessions import write_rig_file

    path = write_rig_file(tmp_path)
    dom = next_domain_id()
    pub = NodeProcess("publisher", {"file": str(path)}, dom, tmp_path / "pub.log")
    try:
        got = tf_static_echo(dom, ["cam1_optical_frame", "cam2_optical_frame"])
        assert got["rc"] == 0, got["output"] + pub.log()
        for k in (1, 2):
            sent = got["by_child"][f"cam{k}_optical_frame"]
            assert sent["parent"] == "cam0_optical_frame"
            np.testing.assert_allclose(sent["translation"], [0.1 * k, 0.0, 0.0], rtol=0, atol=1e-9)
    finally:
        assert pub.stop() == 0, pub.log()
