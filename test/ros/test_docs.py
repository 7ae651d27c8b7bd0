"""docs/nodes.md's tables come from the nodes' own tables (python -m pascal_calib_ros.ros.docs), and
the topic and service table is the running node's (issue 23)."""

from __future__ import annotations

import pytest
from ros_harness import NodeProcess, RosClient, next_domain_id, require_netns

from pascal_calib_ros.ros.docs import PAGE, TABLES, render
from pascal_calib_ros.ros.interfaces import CALIBRATION_NODE_INTERFACES, STEREO_NODE_INTERFACES
from pascal_calib_ros.ros.params import PARAMS


def test_the_node_page_is_generated_from_the_tables() -> None:
    text = PAGE.read_text()
    assert render(text) == text, "docs/nodes.md is stale: run `make docs` (python -m pascal_calib_ros.ros.docs)"
    for name in TABLES:
        assert f"<!-- generated: {name} -->" in text
    assert all(f"| `{p.name}` |" in text for p in PARAMS)


def test_a_stale_page_is_detected() -> None:
    text = PAGE.read_text()
    stale = text.replace(f"| `{PARAMS[0].name}` |", f"| `{PARAMS[0].name}_old` |", 1)
    assert render(stale) != stale and render(stale) == text


def _running_interfaces(params: dict, tmp_path) -> set[str]:
    """The topics and services of a running calibration node started with ``params`` (parameter
    services left out)."""
    domain = next_domain_id()
    node = NodeProcess("calibration_node", params, domain, tmp_path / "node.log")
    client = RosClient(domain)
    try:
        def names() -> set[str]:
            try:
                pubs = client.node.get_publisher_names_and_types_by_node("pascal_calib", "/")
                subs = client.node.get_subscriber_names_and_types_by_node("pascal_calib", "/")
                srvs = client.node.get_service_names_and_types_by_node("pascal_calib", "/")
            except Exception:  # not discovered yet (rclpy's NodeNameNonExistentError)
                return set()
            return {n for n, _ in pubs} | {n for n, _ in subs} | {n for n, _ in srvs}

        assert client.spin_until(lambda: "/pascal_calib/calibrate" in names(), 30.0), node.log()
        client.spin_until(lambda: False, 1.0)
        return {n for n in names() if not n.startswith(("/parameter_events", "/rosout", "/pascal_calib/describe",
                                                          "/pascal_calib/get_", "/pascal_calib/list_",
                                                          "/pascal_calib/set_", "/pascal_calib/get_type"))}
    finally:
        client.close()
        node.stop()


def _table(interfaces) -> set[str]:
    return {("/pascal_calib/" + i.name[2:]) if i.name.startswith("~/") else i.name if i.name.startswith("/")
            else "/" + i.name for i in interfaces}


@pytest.mark.ros
@require_netns
def test_the_interface_table_is_the_running_nodes(tmp_path) -> None:
    """Every topic and service of the table (with the options that make it exist) on a running
    node, and nothing the table does not list."""
    seen = _running_interfaces({"robot_pose_topic": "/tool_pose"}, tmp_path)
    table = {t.replace("/robot_pose_topic", "/tool_pose") for t in _table(CALIBRATION_NODE_INTERFACES)}
    table -= {"/image/compressed"}
    # robot poses are subscribed once a publisher shows their type; the driver's set_camera_info is a client
    assert seen == table - {"/tool_pose"}, (sorted(seen), sorted(table))


@pytest.mark.ros
@require_netns
def test_the_stereo_interface_table_is_the_running_stereo_nodes(tmp_path) -> None:
    seen = _running_interfaces({"mode": "stereo"}, tmp_path)
    table = _table(STEREO_NODE_INTERFACES) - {"/left/image/compressed"}
    assert seen == table, (sorted(seen), sorted(table))
