"""Faults the node survives (issue 34), through the real node over DDS: robot pose stamps that jump
(one pose an hour ahead, a clock step back) do not block later captures and ``~/status`` says what
happened; a calibration file with a null field neither stops the node at start (``guide:=true``)
nor ends it at ``~/verify``: both say which field; a frame that cannot be saved is counted. And, in
this process, the guards every callback goes through and the ``~`` of ``output_dir``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros_harness import NodeProcess, RosClient, latest_status, next_domain_id, require_netns, status_subscription

from pascal_calib_ros.io.camera_yaml import CameraInfoData, write_camera_yaml
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import resolve_target

pytestmark = [require_netns, pytest.mark.ros]  # the real nodes over DDS (make test: inside tools/in_netns)

HOUR_NS = 3600 * 10**9


def _ring_image() -> np.ndarray:
    cam = SessionSpec(width=640, height=480).camera()
    R = np.array([[1, 0, 0], [0, np.cos(0.4), -np.sin(0.4)], [0, np.sin(0.4), np.cos(0.4)]])
    return render_view(resolve_target("ring_a4"), cam, Pose(R, np.array([0.0, 0.0, 0.9])), SensorModel(seed=1)).image


class ArmStream:
    """A resting arm and its camera from the client node: the tool pose at 20 Hz, the same frame of
    the ring at 5 Hz just after the pose of its stamp; both stamped now + :attr:`shift_ns`."""

    def __init__(self, client: RosClient) -> None:
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import Image

        from pascal_calib_ros.io.image_msgs import grey_to_image_fields

        self.client, self.shift_ns, self.ticks = client, 0, 0
        self.fields = grey_to_image_fields(_ring_image())
        self.pub_pose = client.node.create_publisher(PoseStamped, "/tool_pose", 50)
        self.pub_img = client.node.create_publisher(Image, "/image", 5)
        client.node.create_timer(0.05, self.tick)

    def stamp(self, extra_ns: int = 0) -> object:
        from builtin_interfaces.msg import Time

        t = self.client.node.get_clock().now().nanoseconds + self.shift_ns + extra_ns
        return Time(sec=t // 10**9, nanosec=t % 10**9)

    def pose(self, extra_ns: int = 0) -> None:
        from geometry_msgs.msg import PoseStamped

        m = PoseStamped()
        m.header.frame_id = "base_link"
        m.header.stamp = self.stamp(extra_ns)  # type: ignore[assignment]
        m.pose.position.x, m.pose.position.z, m.pose.orientation.w = 0.4, 0.5, 1.0
        self.pub_pose.publish(m)

    def tick(self) -> None:
        from sensor_msgs.msg import Image

        self.ticks += 1
        self.pose()
        if self.ticks % 4 == 0:
            img = Image(**self.fields)
            img.header.stamp = self.stamp()  # type: ignore[assignment]
            img.header.frame_id = "camera"
            self.pub_img.publish(img)


def test_pose_stamps_that_jump_do_not_block_captures(tmp_path: Path) -> None:
    dom = next_domain_id()
    (tmp_path / "session").mkdir()
    (tmp_path / "session" / "frames").write_text("a file where the frames folder should be")  # writing must fail
    cal = NodeProcess("calibration_node", {
        "collect": "on_capture", "robot_pose_topic": "/tool_pose", "capture_timeout": 4.0,
        "output_dir": str(tmp_path / "out"), "session_dir": str(tmp_path / "session")}, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        arm = ArmStream(client)
        assert client.spin_until(lambda: int(latest_status(status).get("robot_poses_received", 0)) > 10
                                 and int(latest_status(status).get("frames_examined", 0)) > 3, 30), cal.log()
        arm.pose(HOUR_NS)  # one pose stamped an hour ahead
        client.spin_until(lambda: False, 1.0)
        r = client.call_trigger("/pascal_calib/capture", timeout=15)
        assert r.success and r.message.startswith("view 0 stored"), f"{r.message}\n{cal.log()}"
        kv = latest_status(status)
        assert "1 set aside for their stamps" in kv["robot_pose_buffer"], kv
        assert "stamped 3600 s after the frame: clock step or wrong stamps" in kv["robot_pose_buffer"], kv
        # the frame could not be written (session/frames is a file): said and counted, the view is kept
        assert "not written to the session folder: cannot write" in r.message, r.message
        assert client.spin_until(lambda: latest_status(status)["session_views_not_written"] == "1", 5), (
            latest_status(status))
        assert "not written to the session folder" in latest_status(status)["last_error"], latest_status(status)
        arm.shift_ns = -HOUR_NS  # a clock step back (a looped bag): frames and poses an hour earlier
        client.spin_until(lambda: False, 1.5)
        r = client.call_trigger("/pascal_calib/capture", timeout=15)
        assert r.success and r.message.startswith("view 1 stored"), f"{r.message}\n{cal.log()}"
        assert client.spin_until(lambda: "started over 1 time(s)" in latest_status(status)["robot_pose_buffer"],
                                 5), latest_status(status)
        r = client.call_trigger("/pascal_calib/reset")
        assert r.success and "cleared 2 view(s)" in r.message
        client.spin_until(lambda: False, 1.0)
        assert "started over" not in latest_status(status)["robot_pose_buffer"]  # ~/reset cleared the buffer
        assert cal.proc.poll() is None
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()


def test_a_calibration_file_with_a_null_field_is_refused_with_the_reason(tmp_path: Path) -> None:
    path = write_camera_yaml(tmp_path / "cam.yaml", CameraInfoData(640, 480, "cam", np.diag([500.0, 500.0, 1.0]),
                                                                   np.zeros(5)))
    doc = yaml.safe_load(path.read_text())
    doc["image_width"] = None
    path.write_text(yaml.safe_dump(doc))
    dom = next_domain_id()
    cal = NodeProcess("calibration_node", {"guide": True, "calibration_file": str(path)}, dom, tmp_path / "cal.log")
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        assert client.spin_until(lambda: bool(status), 30), cal.log()  # it started, with the guide
        assert "image_width must be a positive whole number of pixels, got None" in cal.log(), cal.log()
        assert "drawn with a nominal camera" in cal.log()
        r = client.call_trigger("/pascal_calib/verify")
        assert not r.success and "nothing to verify against" in r.message and "image_width" in r.message, r.message
        assert cal.proc.poll() is None, cal.log()
    finally:
        client.close()
        assert cal.stop() == 0, cal.log()


def test_guards_turn_an_exception_into_an_answer(tmp_path: Path) -> None:
    """In this process, with a real node: a service that raises answers ``success = False`` with the
    reason, a timer's exception is logged, a parameter callback's refuses the change; a frame
    that cannot be saved is counted; ``~`` in output_dir and calibration_file is expanded."""
    import rclpy
    from rclpy.parameter import Parameter
    from std_srvs.srv import Trigger

    from pascal_calib_ros.ros.calibration_node import CalibrationNode
    from pascal_calib_ros.ros.guard import guarded_callback, guarded_parameters, guarded_service, save_frame

    def boom(*_: object) -> None:
        raise TypeError("int() argument must be a string, not 'NoneType'")

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=next_domain_id())
    node = CalibrationNode(context=ctx, parameter_overrides=[Parameter("output_dir", value="~/calib_x"),
                                                             Parameter("calibration_file", value="~/c.yaml"),
                                                             Parameter("record_session", value="never")])
    try:
        r = guarded_service(node, "~/verify", boom)(Trigger.Request(), Trigger.Response())
        assert not r.success and r.message == "~/verify failed: TypeError: int() argument must be a string, not " \
                                              "'NoneType'"
        guarded_callback(node, "status", boom)()  # logged, not raised
        refused = guarded_parameters(node, boom)([])
        assert not refused.successful and "TypeError" in refused.reason
        assert node.p("output_dir") == os.path.expanduser("~/calib_x") and not node.p("output_dir").startswith("~")
        assert node.calibration_path() == Path(os.path.expanduser("~/c.yaml"))
        assert node.recording.folder is None and not Path(os.path.expanduser("~/calib_x")).exists()
        node.frames_not_saved = 0  # save_frame's counter (the stereo node's frames)
        (tmp_path / "frames").write_text("not a folder")
        assert not save_frame(node, tmp_path / "frames" / "v.png", np.zeros((4, 4), np.uint8))
        assert node.frames_not_saved == 1 and "frame not saved: cannot write" in node.last_error
        assert save_frame(node, tmp_path / "ok" / "v.png", np.zeros((4, 4), np.uint8))
        assert (tmp_path / "ok" / "v.png").is_file() and node.frames_not_saved == 1
    finally:
        node.stop()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
