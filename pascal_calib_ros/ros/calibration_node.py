"""ROS 2 calibration node ``pascal_calib`` (executable ``calibration_node``).

Subscribes ``image`` (sensor_msgs/Image) or ``image/compressed`` (``transport:=compressed``),
detects the target in a worker thread (only the newest frame waits; older ones are dropped and
counted), hands each detection to the live session (:mod:`..session.live`: stillness, captures,
diversity), reports progress on ``~/status`` (diagnostic_msgs/DiagnosticArray), draws the live view
on ``~/detections`` while someone listens, acknowledges every examined frame on
``~/examined_frames`` (std_msgs/Header; ``replay_node``'s lock-step mode waits for it), and offers
``~/calibrate``, ``~/reset``, ``~/capture`` and ``~/commit`` (std_srvs/Trigger). ``~/calibrate``
runs the same workflow as the CLI (:mod:`..workflows.intrinsic`, :mod:`..workflows.hand_eye`); a
good result is published on ``~/camera_info`` (and ``~/hand_eye``; reliable, transient local; and on
``/tf_static``, :mod:`.tf_static`) and written to files; a failed calibration publishes nothing and keeps the previous.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from sensor_msgs.srv import SetCameraInfo
from std_msgs.msg import Header

from ..calibrate import SHAPE_CHOICES, CalibrationError, CalibrationOptions, CalibrationResult
from ..calibrate.handeye import HandEyeOptions
from ..detect import Detection, detect_target
from ..errors import PascalCalibError
from ..io import CameraInfoData, ImageConversionError, compressed_to_grey, grey_to_image_fields, image_to_grey
from ..modes import HandEyeMode
from ..session import Answer, LiveSession, Snapshot, max_motion_of, placement_points
from ..workflows import (
    HAND_EYE_FILE,
    ReportRequest,
    ResultPaths,
    ResultSet,
    ResultWriter,
    calibration_file_path,
    detection_params,
    hand_eye_doubts,
    hand_eye_frames,
    run_hand_eye,
    run_intrinsic,
)
from .commit import commit_camera_info
from .conversions import camera_info_msg, transform_msg
from .guard import guarded_callback
from .guide_services import NodeGuide
from .image_subscription import MatchedImageSubscription
from .node_base import LATCHED, CalibrationNodeBase
from .node_session import FileWriteError, NodeSession
from .node_verify import run_verification
from .robot_poses import RobotPoseInput
from .status import status_message
from .tf_static import StaticTransforms

# a frame waits at most this long (wall time, or pose_max_age if longer) for the robot pose published
# for its stamp: the pose comes on another topic and may be late on a loaded machine
POSE_ARRIVAL_WAIT_S = 1.0


class CalibrationNode(CalibrationNodeBase):
    MODE = "mono"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.pose_topic = str(self.p("robot_pose_topic"))
        self.session = LiveSession(self.p("min_views"), self.p("max_views"), self.p("min_view_distance"),
                                   max_motion_of(float(self.p("max_motion_px")), str(self.p("collect")),
                                                 bool(self.pose_topic), bool(self.p("guide"))), str(self.p("collect")),
                                   board_points=placement_points(self.target))
        self.result: CalibrationResult | None = None
        self.result_msg: CameraInfo | None = None
        self.frames_received = self.frames_dropped = self.frames_bad = self.frames_examined = 0
        self._session_start = (0, 0)  # frames received / dropped before the last ~/reset
        self.frame_id = "camera"
        self.hand_eye_line = ""
        self.hand_eye_result: Any = None  # (HandEyeResult, parent frame, camera frame) of the last ~/calibrate
        self.verify_line = ""
        self.robot: RobotPoseInput | None = None
        self._create_interfaces()
        self.recording = NodeSession(self)  # the session folder (resume), the result sets and their labels
        resumed = self.recording.resume()
        if self.pose_topic:
            self.robot = RobotPoseInput(self, self.pose_topic, lambda: (str(self.p("robot_base_frame")),
                                                                        str(self.p("robot_tool_frame"))))
        self.start()
        folder = self.recording.folder
        self.get_logger().info(
            f"target {self.target.name}, method {self.method}, listening on "
            f"{self.resolve_topic_name(self.topic)} ({self.p('transport')}, qos {self.p('qos')}); "
            f"call {self.resolve_service_name('~/calibrate')} when the status says ready"
            + (f"; session folder {folder.path}" + (f" ({resumed} view(s) resumed)" if resumed else "")
               if folder is not None else ""))

    def _create_interfaces(self) -> None:
        """Publishers, services and the image subscription (docs/nodes.md lists them)."""
        self.pub_info = self.create_publisher(CameraInfo, "~/camera_info", LATCHED)
        self.pub_status = self.create_publisher(DiagnosticArray, "~/status", 10)
        self.pub_det = self.create_publisher(Image, "~/detections", 2)
        # one message per examined frame; transient local so that an acknowledgement sent before
        # a subscriber finished discovery still reaches it (lock-step replays wait for it)
        examined_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE,
                                  durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
        self.pub_examined = self.create_publisher(Header, "~/examined_frames", examined_qos)
        self.pub_hand_eye = self.create_publisher(TransformStamped, "~/hand_eye", LATCHED)
        self.tf_static = StaticTransforms(self)  # the hand-eye transform on /tf_static, with ~/hand_eye
        services = ReentrantCallbackGroup()
        self.add_services({"calibrate": self.run_calibration, "reset": self.reset, "commit": self.commit,
                           "capture": self.capture, "verify": self.verify}, services)
        self.guide = NodeGuide(self, services, LATCHED)  # ~/suggest, ~/skip_suggestion, the person guide (guide:=true)
        self.set_info_client = self.create_client(SetCameraInfo, self.p("set_camera_info_service"),
                                                  callback_group=services)
        compressed = self.p("transport") == "compressed"
        self.topic = "image/compressed" if compressed else "image"
        self.image_sub = MatchedImageSubscription(self, self.topic, CompressedImage if compressed else Image,
                                                  guarded_callback(self, "image callback", self._on_image),
                                                  lambda: str(self.p("qos")), MutuallyExclusiveCallbackGroup())
        self.add_timers({"image subscription check": self.image_sub.ensure, "status": self.publish_status})

    # -- parameters ------------------------------------------------------------------
    def calibration_path(self) -> Path:
        """Where this node's camera YAML is written and read (:func:`calibration_file_path`)."""
        return calibration_file_path(str(self.p("camera_name")), str(self.p("output_dir")),
                                     str(self.p("calibration_file")))

    def apply_changes(self, changes: dict[str, Any]) -> None:
        if "target" in changes:
            self.session.clear()
        motion = None
        if "max_motion_px" in changes or "collect" in changes:
            motion = max_motion_of(float(changes.get("max_motion_px", self.p("max_motion_px"))),
                                   str(changes.get("collect", self.p("collect"))), bool(self.pose_topic),
                                   bool(self.p("guide")))
        if "goal_sigma_px" in changes:
            self.guide.set_goal(float(changes["goal_sigma_px"]))
        if "collect" in changes:
            self.session.collect = str(changes["collect"])
        self.session.set_limits(changes.get("min_views"), changes.get("max_views"), changes.get("min_view_distance"),
                                motion)

    # -- image input ------------------------------------------------------------------
    def _on_image(self, msg: Any) -> None:
        """Executor callback: only hand the newest frame to the worker."""
        with self._pending_cv:
            self.frames_received += 1
            if self.hand_over((msg, time.monotonic())):
                self.frames_dropped += 1

    def process(self, pending: Any) -> None:
        self._process(*pending)

    def examined(self, pending: Any) -> None:
        """Count the examined frame and publish its header on ``~/examined_frames``."""
        msg = pending[0]
        with self._pending_cv:
            self.frames_examined += 1
        try:
            self.pub_examined.publish(msg.header)
        except Exception as e:  # shutting down, or a header that cannot be published
            self.get_logger().warn(f"cannot acknowledge frame: {type(e).__name__}: {e}",
                                   throttle_duration_sec=5.0)

    def _process(self, msg: Any, received_at: float = 0.0) -> None:
        try:
            img = compressed_to_grey(msg) if isinstance(msg, CompressedImage) else image_to_grey(msg)
        except ImageConversionError as e:
            self.frames_bad += 1
            self.session.bad_frame(str(e))
            self.last_error = str(e)
            self.get_logger().warn(f"bad frame: {e}", throttle_duration_sec=5.0)
            return
        if msg.header.frame_id:
            self.frame_id = msg.header.frame_id
        params = detection_params(str(self.p("distortion_model")), float(self.p("gamma")))
        det = detect_target(img, self.target, params,
                            name=f"frame_{self.recording.name_offset + self.frames_received:06d}")
        stamp_ns = int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec)
        poses = self.robot.poses if self.robot is not None else None
        if poses is not None:  # the pose for this stamp may still be on its way (another topic)
            poses.wait_until_covers(stamp_ns, max(float(self.p("pose_max_age")), POSE_ARRIVAL_WAIT_S))
        out = self.session.examine(det, stamp_ns, poses, float(self.p("pose_max_age")), received_at,
                                   drawing=self.pub_det.get_subscription_count() > 0, guide=self.guide.examine(det),
                                   persist=self.recording.persist(img, stamp_ns))
        if out.accepted:
            self.guide.stored(self.session.snapshot().views)  # the next suggestion, on the guide's own thread
        if out.written.startswith("not written"):
            self.last_error = out.written
        vis = self.session.picture(img, det, out)
        if vis is not None:
            vis = self.guide.draw(vis, img.shape[1])
            self.pub_det.publish(Image(header=msg.header, **grey_to_image_fields(vis)))
        if out.accepted:
            self.publish_status()
        self.auto_calibrate(out.ready, out.views)

    # -- status -------------------------------------------------------------------------
    def session_frames(self) -> tuple[int, int]:
        """(frames received, frames dropped unexamined) since the start or the last ``~/reset``."""
        with self._pending_cv:
            received, dropped = self.frames_received, self.frames_dropped
        return received - self._session_start[0], dropped - self._session_start[1]

    def dropped_note(self) -> str:
        """What the dropped frames of this session mean and what to do; empty if none."""
        received, dropped = self.session_frames()
        if not dropped:
            return ""
        return (f"{dropped} of {received} frame(s) arrived while the detector was busy and were dropped "
                "unexamined (only the newest frame waits). Replaying a recording: use replay_node's "
                "lock-step mode (mode:=lockstep, the default) or a lower rate; a live camera: hold "
                "each pose longer")

    def publish_status(self) -> None:
        self.pub_status.publish(status_message(self))

    def _header(self) -> Header:
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id)

    # -- calibration ------------------------------------------------------------------------
    def attempt(self) -> Answer:
        try:
            snap = self.session.snapshot()
            if len(snap.views) < snap.min_views:
                msg = self.session.refusal(snap, self.session_frames()[1], self.dropped_note())
                self.get_logger().warn(f"calibration refused: {msg}")
                return Answer(False, msg)
            opts = CalibrationOptions(method=self.method, distortion=str(self.p("distortion_model")),
                                      zero_skew=bool(self.p("zero_skew")),
                                      min_views=min(snap.min_views, len(snap.views)),
                                      target_shape=SHAPE_CHOICES[str(self.p("target_shape"))])
            if self.p("hand_eye"):
                return self._run_hand_eye(snap, opts)
            return self._run_intrinsic(snap.views, opts)
        except Exception as e:  # never let a numerical failure take the node down
            self.get_logger().error(f"calibration crashed: {type(e).__name__}: {e}")
            return Answer(False, f"calibration failed: {type(e).__name__}: {e}")

    def _run_intrinsic(self, views: list[Detection], opts: CalibrationOptions) -> Answer:
        try:
            out = run_intrinsic(views, self.target, opts, with_cross_validation=bool(self.p("cross_validate")))
        except CalibrationError as e:
            self.get_logger().warn(f"calibration failed: {e}")
            return Answer(False, f"calibration failed: {e}")
        try:
            rs = self._write_outputs(views, out.write, hand_eye=False)
        except FileWriteError as e:
            return Answer(False, f"calibration not published: {e}")
        self._publish_camera(out.assessment.result, out.camera_info(str(self.p("camera_name"))))
        answer = out.answer(str(self.calibration_path())) + f" result={rs.id}"
        for line in out.cross_validation_lines:
            self.log(line, out.halves_agree is True)
        self.get_logger().info(f"calibrated: {answer}")
        self.publish_status()
        return Answer(True, answer)

    def _run_hand_eye(self, snap: Snapshot, opts: CalibrationOptions) -> Answer:
        """Intrinsics and hand-eye in one estimate; publishes CameraInfo and ~/hand_eye only if
        the transform can be stood behind (:func:`~..workflows.hand_eye.hand_eye_doubts`)."""
        def refuse(why: str) -> Answer:
            self.get_logger().warn(f"hand-eye calibration refused: {why}")
            return Answer(False, f"hand-eye calibration failed: {why}")

        if self.robot is None:
            return refuse("no robot poses: set robot_pose_topic")
        with_pose = sum(p is not None for p in snap.robot_poses)
        if with_pose < 3:
            return refuse(f"only {with_pose} of {len(snap.views)} view(s) have a robot pose; need 3 or more "
                          f"(robot poses received on {self.robot.resolved}: "
                          f"{self.robot.poses.received}{'; ' + self.robot.error if self.robot.error else ''})")
        mode = HandEyeMode(self.p("hand_eye"))
        he_opts = HandEyeOptions(mode, arm_accuracy_mm=float(self.p("arm_accuracy_mm")),
                                 arm_accuracy_length=float(self.p("arm_accuracy_length")))
        try:
            out = run_hand_eye(snap.views, snap.robot_poses, self.target, opts, he_opts)
        except CalibrationError as e:  # HandEyeError included
            return refuse(str(e))
        doubts = hand_eye_doubts(out.result)
        if doubts:
            return refuse("the transform is not determined well enough: " + "; ".join(doubts)
                          + " (add views with larger rotations about different axes)")
        frames = hand_eye_frames(mode, str(self.p("robot_base_frame")), str(self.p("robot_tool_frame")),
                                 str(self.p("camera_frame")))
        try:
            rs = self._write_outputs(snap.views, lambda paths, name, report: out.write(paths, name, frames, report),
                                     hand_eye=True)
        except FileWriteError as e:
            return refuse(f"nothing published: {e}")
        path = self.calibration_path()
        self.hand_eye_line, summary = out.answer(frames, len(snap.views), str(path.parent / HAND_EYE_FILE), str(path))
        summary += f" result={rs.id}"
        self.hand_eye_result = (out.result, frames.parent, frames.camera)
        self._publish_camera(out.assessment.result, out.camera_info(str(self.p("camera_name"))))
        tf = transform_msg(out.result.hand_eye, frames.parent, frames.camera, self.get_clock().now().to_msg())
        self.pub_hand_eye.publish(tf)
        if not self.tf_static.send(tf):
            self.get_logger().warn(self.tf_static.unavailable, once=True)
        self.get_logger().info(f"calibrated: {summary}")
        self.publish_status()
        return Answer(True, summary)

    def _publish_camera(self, res: CalibrationResult, info: CameraInfoData) -> None:
        msg = camera_info_msg(info, self._header())
        self.result, self.result_msg = res, msg
        self.pub_info.publish(msg)

    def _write_outputs(self, views: list[Detection], write: ResultWriter, *, hand_eye: bool) -> ResultSet:
        """One result set (:meth:`.node_session.NodeSession.write_result`) written by the outcome's
        ``write``: the camera YAML, its record, ``hand_eye.yaml`` and, with ``output_dir``, the report."""
        name = str(self.p("camera_name"))
        report = ReportRequest(views, self.recording.images()) if self.p("output_dir") else None
        warnings: list[str] = []

        def fill(folder: Path) -> None:
            paths = ResultPaths.in_folder(folder, name, hand_eye=hand_eye, report=report is not None)
            warnings.extend(write(paths, name, report).warnings)
        rs = self.recording.write_result(fill, len(views))
        for w in warnings:
            self.get_logger().warn(w)
        return rs

    # -- services -------------------------------------------------------------------------
    def capture(self) -> Answer:
        """``~/capture``: store the next still frame (:class:`..session.arm_session.CaptureSlot`)."""
        timeout = float(self.p("capture_timeout"))
        captures = self.session.captures
        capture = captures.open(timeout)
        if capture is None:
            return Answer(False, "a capture is already waiting for a still frame; try again")
        ok, answer = captures.wait(capture, timeout)
        self.log(f"capture: {answer}", ok)
        self.publish_status()
        return Answer(ok, answer)

    def verify(self) -> Answer:
        """``~/verify``: the views collected since the last ~/reset against the published calibration
        (:mod:`.node_verify`)."""
        ok, line = run_verification(self)
        if ok:
            self.verify_line = line
        self.log(f"verify: {line}", ok)
        self.publish_status()
        return Answer(ok, line)

    def reset(self) -> Answer:
        """``~/reset``: the views, the pose buffer, the latched suggestions; the session folder starts over."""
        n = self.session.clear()
        if self.robot is not None:  # a session's stamps start over (a looped bag, a restarted driver)
            self.robot.poses.clear()
        self.guide.reset()  # and its latched suggestions
        kept = self.recording.clear()
        self.auto_done_at = -1
        with self._pending_cv:
            self._session_start = (self.frames_received, self.frames_dropped)
        running = " (a running calibration finishes on its own copy of the views)" if self.calibrating.locked() else ""
        live = self.history.live
        answer = (f"cleared {n} view(s){running}{kept}; the live {live.describe() if live else 'result: none'} "
                  "is kept")
        self.get_logger().info(answer)
        self.publish_status()
        return Answer(True, answer)

    def commit(self) -> Answer:
        """``~/commit``: the live result to the driver, unless it is stale (:mod:`..session.result_history`)."""
        problem = self.history.commit_problem()
        if problem:
            ok, answer = False, problem
        else:
            live = self.history.live
            ok, answer = commit_camera_info(self.set_info_client, self.result_msg)
            answer = f"{live.describe() if live else 'result'}: {answer}"
        self.log(answer, ok)
        return Answer(ok, answer)


def main(args: list[str] | None = None) -> int:
    from .node_mode import make_calibration_node
    from .spin import run_node

    return run_node(lambda: make_calibration_node(CalibrationNode), (PascalCalibError,), "pascal_calib",
                    lambda: MultiThreadedExecutor(num_threads=6), args)


if __name__ == "__main__":
    raise SystemExit(main())
