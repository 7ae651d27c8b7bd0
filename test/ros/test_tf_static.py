"""``ros/tf_static.py`` over DDS: what a late tf2 listener (another process) receives after transforms are
added and replaced, through the TFMessage publisher of the PyPI venv and through a ``tf2_ros`` broadcaster
(tf2_ros is not on PyPI: a module with the broadcaster of the tf2_ros versions that keep the first
transform per child frame stands in for it, publishing the real TFMessage on /tf_static)."""

from __future__ import annotations

import sys
import types
from collections.abc import Iterator
from typing import Any

import pytest
from ros_harness import RosClient, next_domain_id, require_netns, tf_static_echo

pytestmark = [require_netns, pytest.mark.ros]


class _AppendOnlyBroadcaster:
    """tf2_ros's StaticTransformBroadcaster as some versions have it: a child frame seen before keeps
    its first transform."""

    def __init__(self, node: Any, qos: Any = None) -> None:
        from tf2_msgs.msg import TFMessage

        self.pub_tf = node.create_publisher(TFMessage, "/tf_static", qos)
        self.net_message = TFMessage()
        self._child_frame_ids: set[str] = set()

    def sendTransform(self, transform: list[Any]) -> None:  # tf2_ros's name
        for t in transform:
            if t.child_frame_id not in self._child_frame_ids:
                self._child_frame_ids.add(t.child_frame_id)
                self.net_message.transforms.append(t)
        self.pub_tf.publish(self.net_message)


@pytest.fixture(params=["tf2_msgs", "tf2_ros"])
def via(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    if request.param == "tf2_ros":
        fake = types.SimpleNamespace(StaticTransformBroadcaster=_AppendOnlyBroadcaster)
        monkeypatch.setitem(sys.modules, "tf2_ros", fake)
    else:
        monkeypatch.setitem(sys.modules, "tf2_ros", None)  # import fails: the venv's case
    yield request.param


def _tf(parent: str, child: str, x: float) -> Any:
    from geometry_msgs.msg import TransformStamped

    t = TransformStamped(child_frame_id=child)
    t.header.frame_id = parent
    t.transform.translation.x = x
    return t


def test_late_listener_gets_every_transform_with_its_latest_value(via: str) -> None:
    from pascal_calib_ros.ros.tf_static import StaticTransforms

    dom = next_domain_id()
    client = RosClient(dom, "broadcaster")
    try:
        st = StaticTransforms(client.node)
        assert st.unavailable == "" and st.via.startswith(via), (st.via, st.unavailable)
        assert st.send(_tf("tool0", "camera_optical_frame", 0.1))
        assert st.send(_tf("left", "right", 0.2))
        assert st.send(_tf("tool0", "camera_optical_frame", 0.3))  # a recalibration replaces it
        assert st.describe() == "tool0 -> camera_optical_frame, left -> right"
        got = {}
        for _ in range(2):  # spin the broadcaster's node while the listener process runs
            got = tf_static_echo(dom, ["camera_optical_frame", "right"], timeout=10)
            if got["rc"] == 0:
                break
        assert got["rc"] == 0, got["output"]
        assert len(got["transforms"]) == 2 and got["messages"] == 1, got
        assert got["by_child"]["camera_optical_frame"]["translation"][0] == 0.3
        assert got["by_child"]["right"]["parent"] == "left" and got["by_child"]["right"]["translation"][0] == 0.2
    finally:
        client.close()
