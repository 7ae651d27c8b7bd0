"""ROS 2 calibration node ``pascal_calib`` (executable ``calibration_node``).

Subscribes ``image`` (sensor_msgs/Image) or ``image/compressed`` (``transport:=compressed``),
detects the target in a worker thread (only the newest frame waits; older ones are dropped and
counted), keeps the features of views that add diversity, reports progress on ``~/status``
(diagnostic_msgs/DiagnosticArray), draws the live view on ``~/detections`` while someone listens
(the detection, the stored views' footprints, the coverage bars: :mod:`..calibrate.live_overlay`),
acknowledges every frame the detector has examined on ``~/examined_frames`` (std_msgs/Header,
the frame's own header; ``replay_node``'s lock-step mode waits for it), and offers
``~/calibrate``, ``~/reset`` and ``~/commit`` (std_srvs/Trigger). A good result is published on
``~/camera_info`` (reliable, transient local) and written as camera_calibration_parsers YAML; a
failed calibration publishes nothing and keeps the previous.

Robot-arm sessions (:mod:`..calibrate.arm_session`): ``~/capture`` (std_srvs/Trigger) stores the
next still frame as a view whatever it resembles (``collect:=on_capture``: only captures store
views); frames are used only while the target (and the robot) stand still (``max_motion_px``);
with ``robot_pose_topic`` (geometry_msgs/PoseStamped or TransformStamped: the tool in the robot
base) every view gets the robot pose at its image stamp, and with ``hand_eye`` (eye_in_hand |
eye_to_hand) ``~/calibrate`` also solves the hand-eye transform and publishes it on
``~/hand_eye`` (geometry_msgs/TransformStamped, reliable, transient local). TF lookup of the
robot pose is not implemented: the pose topic is the supported (and tested) path.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from sensor_msgs.srv import SetCameraInfo
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from ..analysis.cross_validation import cross_validate
from ..calibrate.diagnostics import feature_points, view_hulls
from ..calibrate.pipeline import METHODS, CalibrationError, CalibrationOptions, CalibrationResult, calibrate
from ..calibrate.refine import DISTORTION_MODELS, SHAPE_CHOICES
from ..detect.detection import Detection, DetectionParams
from ..detect.target_detector import detect_target
from ..errors import PascalCalibError
from ..geometry.camera import rectified_projection
from ..geometry.lens import lens_model
from ..geometry.transform import Transform, TransformError
from ..io.camera_yaml import CameraInfoData, write_camera_yaml
from ..io.image_msgs import ImageConversionError, compressed_to_grey, grey_to_image_fields, image_to_grey
from ..io.images import read_grey
from ..session.arm_session import (
    MOVING,
    CaptureSlot,
    PoseBuffer,
    StillnessGate,
    capture_is_final,
    hand_eye_doubts,
    stored_message,
)
from ..session.collector import ViewCollector
from ..session.overlay import draw_live_overlay
from ..targets import Target, TargetError, resolve_target
from .conversions import camera_info_msg


class ParameterError(PascalCalibError):
    """A node parameter that cannot work (refused at start, exit code 2, or at run time)."""

@dataclass(frozen=True)
class Param:
    name: str
    default: Any
    description: str
    choices: tuple[str, ...] = ()
    int_range: tuple[int, int] | None = None
    float_range: tuple[float, float] | None = None


# The one declaration table of the node's parameters.
PARAMS = (
    Param("target", "ring_a4", "target YAML path or packaged target name (ring_a4, pascal_board_a3, ...)"),
    Param("method", "", "ring | pt2 | pt1 | huang | grid | zhang; empty: the target's natural method",
          choices=("", *METHODS)),
    Param("min_views", 8, "views needed before calibrating (>= 3)", int_range=(3, 1000)),
    Param("max_views", 40, "views kept at most (bounded memory)", int_range=(3, 1000)),
    Param("camera_name", "camera", "camera_name written to the YAML and CameraInfo consumers"),
    Param("output_dir", "", "if set: accepted frames, the YAML and a JSON summary are written here"),
    Param("calibration_file", "", "YAML path; empty: <output_dir>/<camera_name>.yaml, else "
          "~/.ros/camera_info/<camera_name>.yaml"),
    Param("zero_skew", True, "estimate K with zero skew"),
    Param("distortion_model", "plumb_bob", "lens model: plumb_bob | plumb_bob_k3_fixed | radial | none | "
          "rational_polynomial | equidistant (fisheye)",
          choices=tuple(DISTORTION_MODELS)),
    Param("target_shape", "", "also estimate the printed sheet's shape (grid and checkerboard targets): "
          "warp (out-of-plane bend), pitch (y/x scale ratio), all; empty: nominal flat sheet",
          choices=tuple(SHAPE_CHOICES)),
    Param("cross_validate", False, "~/calibrate also calibrates two interleaved halves of the views and compares "
          "them against their projection uncertainty (needs 2 x min_views views; not with hand_eye)"),
    Param("gamma", 1.0, "linearise intensities with this display gamma before locating edges (1: a linear "
          "sensor, as most machine-vision cameras by default; about 2.2: sRGB webcams); see the README, Trust",
          float_range=(0.2, 5.0)),
    Param("auto_calibrate", False, "calibrate as soon as the coverage is complete"),
    Param("qos", "auto", "image subscription reliability: auto (match the publisher) | reliable | best_effort",
          choices=("auto", "reliable", "best_effort")),
    Param("transport", "raw", "raw (sensor_msgs/Image on 'image') | compressed ('image/compressed')",
          choices=("raw", "compressed")),
    Param("set_camera_info_service", "camera/set_camera_info", "driver's sensor_msgs/SetCameraInfo service"),
    Param("min_view_distance", 0.08, "diversity threshold between stored views (L1 in x, y, size, skew)",
          float_range=(0.0, 2.0)),
    Param("collect", "auto", "auto: store frames that add diversity | on_capture: only ~/capture stores views",
          choices=("auto", "on_capture")),
    Param("capture_timeout", 5.0, "~/capture waits this many seconds for a still frame", float_range=(0.1, 600.0)),
    Param("max_motion_px", -1.0, "a frame is used only if the target's features moved less than this since "
          "the previous frame (and the robot did not move); 0: no check; -1: 0.5 px with robot_pose_topic "
          "or collect:=on_capture, else no check", float_range=(-1.0, 1000.0)),
    Param("robot_pose_topic", "", "geometry_msgs/PoseStamped or TransformStamped of the tool in the robot base "
          "(empty: no robot poses)"),
    Param("pose_max_age", 0.1, "a view's robot pose is interpolated from samples at most this many seconds "
          "from its image stamp; a frame waits up to this long (wall time) for a pose sample at or after "
          "its stamp", float_range=(0.001, 10.0)),
    Param("robot_base_frame", "base_link", "the robot base frame (robot poses must be in it)"),
    Param("robot_tool_frame", "tool0", "the robot tool (flange) frame the poses describe"),
    Param("camera_frame", "camera_optical_frame", "child frame of the published hand-eye transform"),
    Param("hand_eye", "", "'' (off) | eye_in_hand | eye_to_hand: ~/calibrate also solves hand-eye",
          choices=("", "eye_in_hand", "eye_to_hand")),
    Param("arm_accuracy_mm", 0.2, "the arm's systematic position error (absolute accuracy over the session's "
          "workspace, per axis) that no session can measure: its share is added to the hand-eye std; 0: left out",
          float_range=(0.0, 100.0)),
    Param("arm_accuracy_length", 0.3, "metres over which that error changes (its correlation length)",
          float_range=(0.01, 100.0)),
)
READ_ONLY = {"transport", "robot_pose_topic"}
# a frame waits at most this long (wall time, or pose_max_age if longer) for the robot pose published
# for its stamp: the pose comes on another topic and may be late on a loaded machine
POSE_ARRIVAL_WAIT_S = 1.0
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
MOTION_AUTO_PX = 0.5


class CalibrationNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("pascal_calib", **kwargs)
        for p in PARAMS:
            desc = ParameterDescriptor(description=p.description + (f" ({', '.join(p.choices)})" if p.choices else ""),
                                       read_only=p.name in READ_ONLY)
            if p.int_range:
                desc.integer_range = [IntegerRange(from_value=p.int_range[0], to_value=p.int_range[1], step=1)]
            if p.float_range:
                desc.floating_point_range = [FloatingPointRange(from_value=p.float_range[0],
                                                                to_value=p.float_range[1], step=0.0)]
            self.declare_parameter(p.name, p.default, desc)
        problems = self._validate({p.name: self.get_parameter(p.name).value for p in PARAMS})
        if problems:
            raise ParameterError("invalid parameters: " + "; ".join(problems))
        self.target: Target = resolve_target(self.p("target"))
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.lock = threading.Lock()
        self.collector = ViewCollector(self.p("min_views"), self.p("max_views"), self.p("min_view_distance"))
        # outlines (convex hulls of the feature points) of the stored views for ~/detections;
        # computed once per stored view, guarded by self.lock with the collector
        self.footprints: list[np.ndarray] = []
        self.result: CalibrationResult | None = None
        self.result_msg: CameraInfo | None = None
        self.frames_received = 0
        self.frames_dropped = 0
        self.frames_bad = 0
        self.frames_examined = 0
        # frames received / dropped before the last ~/reset (the refusal speaks of this session)
        self._session_start = (0, 0)
        self.last_error = ""
        self.frame_id = "camera"
        self.calibrating = threading.Lock()
        self.auto_done_at = -1

        # robot-arm sessions
        self.pose_topic = str(self.p("robot_pose_topic"))
        self.poses: PoseBuffer | None = PoseBuffer() if self.pose_topic else None
        self.pose_sub: Any = None
        self.pose_type = ""
        self.pose_error = ""
        self.poses_ignored = 0
        self.gate = StillnessGate(self._max_motion(self.p("max_motion_px"), self.p("collect"), self.pose_topic))
        self.captures = CaptureSlot()
        self.hand_eye_line = ""

        self._pending: Any = None
        self._pending_cv = threading.Condition()
        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work, name="detector", daemon=True)

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
        self.pub_info = self.create_publisher(CameraInfo, "~/camera_info", latched)
        self.pub_status = self.create_publisher(DiagnosticArray, "~/status", 10)
        self.pub_det = self.create_publisher(Image, "~/detections", 2)
        # one message per examined frame; transient local so that an acknowledgement sent before
        # a subscriber finished discovery still reaches it (lock-step replays wait for it)
        examined_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE,
                                  durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
        self.pub_examined = self.create_publisher(Header, "~/examined_frames", examined_qos)
        from geometry_msgs.msg import TransformStamped

        self.pub_hand_eye = self.create_publisher(TransformStamped, "~/hand_eye", latched)

        services = ReentrantCallbackGroup()
        self.create_service(Trigger, "~/calibrate", self._srv_calibrate, callback_group=services)
        self.create_service(Trigger, "~/reset", self._srv_reset, callback_group=services)
        self.create_service(Trigger, "~/commit", self._srv_commit, callback_group=services)
        self.create_service(Trigger, "~/capture", self._srv_capture, callback_group=services)
        self.set_info_client = self.create_client(SetCameraInfo, self.p("set_camera_info_service"),
                                                  callback_group=services)

        self._image_group = MutuallyExclusiveCallbackGroup()
        self.sub: Any = None
        self.sub_reliability: ReliabilityPolicy | None = None
        self.topic = "image/compressed" if self.p("transport") == "compressed" else "image"
        self._ensure_subscription()
        self.create_timer(1.0, self._ensure_subscription, callback_group=MutuallyExclusiveCallbackGroup())
        self.create_timer(1.0, self.publish_status, callback_group=MutuallyExclusiveCallbackGroup())
        self._pose_group = MutuallyExclusiveCallbackGroup()
        if self.pose_topic:
            self._ensure_pose_subscription()
            self.create_timer(0.5, self._ensure_pose_subscription, callback_group=MutuallyExclusiveCallbackGroup())
        self._worker.start()
        self.get_logger().info(
            f"target {self.target.name}, method {self.method}, listening on "
            f"{self.resolve_topic_name(self.topic)} ({self.p('transport')}, qos {self.p('qos')}); "
            f"call {self.resolve_service_name('~/calibrate')} when the status says ready")

    # -- parameters ------------------------------------------------------------------
    def p(self, name: str) -> Any:
        return self.get_parameter(name).value

    @property
    def method(self) -> str:
        return str(self.p("method") or self.target.default_method())

    def _validate(self, values: dict[str, Any]) -> list[str]:
        problems = []
        table = {p.name: p for p in PARAMS}
        for name, value in values.items():
            p = table.get(name)
            if p is None:
                continue
            if p.choices and value not in p.choices:
                problems.append(f"{name}={value!r} is not one of {', '.join(repr(c) for c in p.choices)}")
        target_value = values.get("target", self.p("target") if self.has_parameter("target") else None)
        if target_value is not None:
            try:
                t = resolve_target(str(target_value))
                current = self.get_parameter("method").value if self.has_parameter("method") else ""
                method = values.get("method", current)
                if method and method not in t.methods():
                    problems.append(f"method {method!r} does not fit target {t.name} "
                                    f"(supports {', '.join(t.methods())})")
                shape = values.get("target_shape", self.p("target_shape")
                                   if self.has_parameter("target_shape") else "")
                if shape and not (t.grids or t.checkerboards):
                    problems.append(f"target_shape needs a grid or checkerboard target; {t.name} has "
                                    "neither")
            except TargetError as e:
                problems.append(f"target: {e}")
        mn = values.get("min_views", self.p("min_views") if self.has_parameter("min_views") else 3)
        mx = values.get("max_views", self.p("max_views") if self.has_parameter("max_views") else 1000)
        if int(mx) < int(mn):
            problems.append(f"max_views {mx} < min_views {mn}")
        he = values.get("hand_eye", self.p("hand_eye") if self.has_parameter("hand_eye") else "")
        topic = values.get("robot_pose_topic", self.p("robot_pose_topic")
                           if self.has_parameter("robot_pose_topic") else "")
        if he and not topic:
            problems.append(f"hand_eye={he!r} needs robot poses: set robot_pose_topic")
        motion = values.get("max_motion_px")
        if motion is not None and float(motion) < 0 and float(motion) != -1.0:
            problems.append(f"max_motion_px={motion}: 0 (off), -1 (auto) or a positive threshold in px")
        return problems

    @staticmethod
    def _max_motion(value: Any, collect: Any, pose_topic: str | None = None) -> float:
        """The stillness threshold in force (-1: 0.5 px for robot sessions, else off)."""
        v = float(value)
        if v >= 0:
            return v
        return MOTION_AUTO_PX if (pose_topic or collect == "on_capture") else 0.0

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        values = {p.name: p.value for p in params}
        problems = self._validate(values)
        if problems:
            return SetParametersResult(successful=False, reason="; ".join(problems))
        with self.lock:
            if "target" in values:
                self.target = resolve_target(str(values["target"]))
                self.collector.clear()
                self.footprints.clear()
            if "min_views" in values:
                self.collector.min_views = int(values["min_views"])
            if "max_views" in values:
                self.collector.max_views = int(values["max_views"])
            if "min_view_distance" in values:
                self.collector.min_distance = float(values["min_view_distance"])
            if "max_motion_px" in values or "collect" in values:
                self.gate.max_motion_px = self._max_motion(values.get("max_motion_px", self.p("max_motion_px")),
                                                           values.get("collect", self.p("collect")), self.pose_topic)
        return SetParametersResult(successful=True)

    # -- image input ------------------------------------------------------------------
    def _wanted_reliability(self) -> ReliabilityPolicy:
        mode = self.p("qos")
        if mode == "reliable":
            return ReliabilityPolicy.RELIABLE
        if mode == "best_effort":
            return ReliabilityPolicy.BEST_EFFORT
        infos = self.get_publishers_info_by_topic(self.resolve_topic_name(self.topic))
        if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
            return ReliabilityPolicy.BEST_EFFORT  # a reliable subscriber would never connect
        return ReliabilityPolicy.RELIABLE  # no loss of large frames (and the default before anyone publishes)

    def _ensure_subscription(self) -> None:
        want = self._wanted_reliability()
        if self.sub is not None and want == self.sub_reliability:
            return
        if self.sub is not None:
            self.destroy_subscription(self.sub)
        qos = QoSProfile(depth=2, reliability=want, history=HistoryPolicy.KEEP_LAST)
        msg_type = CompressedImage if self.p("transport") == "compressed" else Image
        self.sub = self.create_subscription(msg_type, self.topic, self._on_image, qos,
                                            callback_group=self._image_group)
        self.sub_reliability = want
        self.get_logger().info(f"subscribed to {self.resolve_topic_name(self.topic)} with "
                               f"{'reliable' if want == ReliabilityPolicy.RELIABLE else 'best-effort'} QoS")

    def _on_image(self, msg: Any) -> None:
        """Executor callback: only hand the newest frame to the worker."""
        with self._pending_cv:
            self.frames_received += 1
            if self._pending is not None:
                self.frames_dropped += 1
            self._pending = (msg, time.monotonic())
            self._pending_cv.notify()

    def _work(self) -> None:
        while not self._stop.is_set():
            with self._pending_cv:
                while self._pending is None and not self._stop.is_set():
                    self._pending_cv.wait(0.2)
                pending, self._pending = self._pending, None
            if pending is None:
                continue
            msg, received_at = pending
            try:
                self._process(msg, received_at)
            except Exception as e:  # a bad frame must never stop the node
                self.frames_bad += 1
                self.last_error = f"frame processing failed: {type(e).__name__}: {e}"
                self.get_logger().error(self.last_error)
            finally:
                self._acknowledge(msg)

    def _acknowledge(self, msg: Any) -> None:
        """Count the examined frame and publish its header on ``~/examined_frames``."""
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
            with self.lock:
                self.frames_bad += 1
                self.collector._reject(f"bad frame: {e}")
                self.last_error = str(e)
            self.get_logger().warn(f"bad frame: {e}", throttle_duration_sec=5.0)
            return
        if msg.header.frame_id:
            self.frame_id = msg.header.frame_id
        with self.lock:
            target = self.target
        params = DetectionParams.for_lens(lens_model(str(self.p("distortion_model"))).wide,
                                          gamma=float(self.p("gamma")))
        det = detect_target(img, target, params, name=f"frame_{self.frames_received:06d}")
        stamp_ns = int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec)
        if self.poses is not None:  # the pose for this stamp may still be on its way (another topic)
            self.poses.wait_until_covers(stamp_ns, max(float(self.p("pose_max_age")), POSE_ARRIVAL_WAIT_S))
        verdict = self.gate.examine(det, stamp_ns, self.poses, float(self.p("pose_max_age")))
        capture = self.captures.for_frame(received_at)
        answer: tuple[bool, str] | None = None
        accepted = False
        why = verdict.reason or ("ok" if det.ok else det.reason)  # the frame's verdict on ~/detections
        drawing = self.pub_det.get_subscription_count() > 0
        with self.lock:
            if capture is not None:
                if capture_is_final(verdict, self.poses is not None):
                    if verdict.usable:
                        accepted, why = self.collector.offer(det, verdict.robot_pose, force=True)
                    else:
                        accepted, why = self.collector._reject(verdict.reason)
                    answer = (accepted, stored_message(len(self.collector.views) - 1, det, verdict.robot_pose)
                              if accepted else f"nothing stored: {why}")
                    why = answer[1]
                else:
                    self.collector._reject(verdict.reason)
                    self.captures.note(capture, verdict.reason)
            elif self.p("collect") == "auto":
                if verdict.usable:
                    accepted, why = self.collector.offer(det, verdict.robot_pose)
                    why = f"view {len(self.collector.views) - 1} stored" if accepted else f"ok; not stored: {why}"
                else:
                    self.collector._reject(verdict.reason)
            elif verdict.usable:
                why = "ok; ~/capture stores a view (collect:=on_capture)"
            if accepted:  # only stored views cost a hull
                self.footprints.extend(view_hulls([feature_points(det)]))
            n = len(self.collector.views)
            ready = self.collector.ready
            overlay = (list(self.footprints), self.collector.coverage(), self.collector.min_views) if drawing else None
        if capture is not None and answer is not None:
            self.captures.finish(capture, *answer)
        if accepted and self.p("output_dir"):
            out = Path(self.p("output_dir")) / "frames"
            out.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(out / f"{det.name}.png"), img)  # the report's worst views are read back by name
        if overlay is not None:
            footprints, coverage, min_views = overlay
            vis = draw_live_overlay(img, det, footprints, coverage, n, min_views, ready, why,
                                    verdict_ok=verdict.usable and (accepted or capture is None))
            self.pub_det.publish(Image(header=msg.header, **grey_to_image_fields(vis)))
        if accepted:
            self.publish_status()
        if ready and self.p("auto_calibrate") and self.auto_done_at != n and not self.calibrating.locked():
            self.auto_done_at = n
            threading.Thread(target=self.run_calibration, name="auto-calibrate", daemon=True).start()

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
        with self.lock:
            cov = self.collector.coverage()
            n = len(self.collector.views)
            ready = self.collector.ready
            rejected = dict(self.collector.rejected)
            last_rej = self.collector.last_rejection
            result = self.result
        _, session_dropped = self.session_frames()
        st = DiagnosticStatus(name=f"{self.get_name()}: calibration", hardware_id=str(self.p("camera_name")))
        if self.calibrating.locked():
            st.level, st.message = DiagnosticStatus.OK, "calibrating"
        elif self.pose_error:
            st.level, st.message = DiagnosticStatus.ERROR, self.pose_error
        elif ready:
            st.level, st.message = DiagnosticStatus.OK, f"ready: {n} views; call ~/calibrate"
        else:
            st.level = DiagnosticStatus.WARN
            st.message = (f"collecting: {n}/{self.collector.min_views} views, coverage "
                          + " ".join(f"{k} {v:.2f}" for k, v in cov.items()))
            if session_dropped:
                st.message += (f"; {session_dropped} frame(s) dropped while the detector was busy "
                               "(replay: use lock-step or a lower rate)")
        kv = {
            "views_accepted": n, "views_rejected": sum(rejected.values()), "ready": ready,
            "frames_received": self.frames_received, "frames_examined": self.frames_examined,
            "frames_dropped": self.frames_dropped, "frames_dropped_session": session_dropped,
            "frames_bad": self.frames_bad, "last_rejection": last_rej, "last_error": self.last_error,
            "frames_dropped_note": self.dropped_note(),
            **{f"coverage_{k}": round(v, 3) for k, v in cov.items()},
            **{f"rejected: {k}": v for k, v in sorted(rejected.items())},
            "result": result.summary_line() if result else "",
            "collect": self.p("collect"), "max_motion_px": self.gate.max_motion_px,
            "captures_stored": self.captures.stored, "captures_refused": self.captures.refused,
        }
        if self.pose_topic:
            kv.update({"robot_pose_topic": self.resolve_topic_name(self.pose_topic),
                       "robot_pose_type": self.pose_type or "unknown (no publisher seen)",
                       "robot_poses_received": self.poses.received if self.poses else 0,
                       "robot_poses_ignored": self.poses_ignored, "robot_pose_error": self.pose_error,
                       "views_with_robot_pose": sum(p is not None for p in self.collector.robot_poses)})
        if self.p("hand_eye"):
            kv["hand_eye"] = self.hand_eye_line
        st.values = [KeyValue(key=k, value=str(v)) for k, v in kv.items()]
        self.pub_status.publish(DiagnosticArray(header=self._header(), status=[st]))

    def _header(self) -> Header:
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id)

    # -- services -------------------------------------------------------------------------
    def run_calibration(self) -> tuple[bool, str]:
        if not self.calibrating.acquire(blocking=False):
            return False, "a calibration is already running; try again when it finishes"
        try:
            with self.lock:
                views = list(self.collector.views)
                robot_poses = list(self.collector.robot_poses)
                target = self.target
                min_views = self.collector.min_views
                rejected = dict(self.collector.rejected)
            if len(views) < min_views:
                rejections = f"rejections: {rejected or 'none'}"
                dropped = self.dropped_note()
                moving = rejected.get(MOVING, 0)
                # every cause that applies, the most frequent first: frames dropped unexamined, moving frames
                causes = []
                if moving and moving >= sum(rejected.values()) / 2:
                    causes.append(f"{moving} frame(s) were moving (features moved max_motion_px "
                                  f"{self.gate.max_motion_px:g} px or more between frames, or the robot moved): hold "
                                  "the target and the arm still at each pose")
                if dropped:
                    causes.insert(0 if self.session_frames()[1] > moving else len(causes), dropped)
                if causes:
                    msg = f"{len(views)} view(s) collected; need {min_views}. {'. '.join(causes)} ({rejections})"
                elif self.p("collect") == "on_capture":
                    msg = (f"{len(views)} view(s) collected; need {min_views}. Call ~/capture at each pose "
                           f"(collect:=on_capture; {rejections})")
                else:
                    msg = (f"{len(views)} view(s) collected; need {min_views}. Move the target through the "
                           f"image ({rejections})")
                self.get_logger().warn(f"calibration refused: {msg}")
                return False, msg
            opts = CalibrationOptions(method=self.method, distortion=str(self.p("distortion_model")),
                                      zero_skew=bool(self.p("zero_skew")), min_views=min(min_views, len(views)),
                                      target_shape=SHAPE_CHOICES[str(self.p("target_shape"))])
            t0 = time.perf_counter()
            mode = str(self.p("hand_eye"))
            if mode:
                return self._run_hand_eye(views, robot_poses, target, opts, mode, t0)
            try:
                res = calibrate(views, target, opts)
            except CalibrationError as e:
                self.get_logger().warn(f"calibration failed: {e}")
                return False, f"calibration failed: {e}"
            except Exception as e:  # never let a numerical failure take the node down
                self.get_logger().error(f"calibration crashed: {type(e).__name__}: {e}")
                return False, f"calibration failed: {type(e).__name__}: {e}"
            dt = time.perf_counter() - t0
            msg = camera_info_msg(res, str(self.p("camera_name")), self._header())
            path = self._write_outputs(res, views)
            with self.lock:
                self.result, self.result_msg = res, msg
            self.pub_info.publish(msg)
            summary = f"{res.summary_line()} time={dt:.2f}s yaml={path}; {res.projection_line()}"
            if res.warnings:
                summary += " warnings: " + "; ".join(res.warnings)
            if self.p("cross_validate"):  # a refusal or a disagreement is reported, the calibration stands
                try:
                    cv = cross_validate(views, target, opts)
                    line = f"{cv.summary_line()}; {'' if cv.agree else 'WARNING: '}{cv.message}"
                except CalibrationError as e:
                    cv, line = None, f"cross-validation not possible: {e}"
                except Exception as e:  # never let a numerical failure take the node down
                    cv, line = None, f"cross-validation failed: {type(e).__name__}: {e}"
                (self.get_logger().info if cv is not None and cv.agree else self.get_logger().warn)(line)
                summary += f"; {line}"
            self.get_logger().info(f"calibrated: {summary}")
            self.publish_status()
            return True, summary
        finally:
            self.calibrating.release()

    def _run_hand_eye(self, views: list[Detection], robot_poses: list[Transform | None], target: Target,
                      opts: CalibrationOptions, mode: str, t0: float) -> tuple[bool, str]:
        """Intrinsics and hand-eye in one estimate; publishes CameraInfo and ~/hand_eye only if
        the transform can be stood behind (module docstring)."""
        def refuse(why: str) -> tuple[bool, str]:
            self.get_logger().warn(f"hand-eye calibration refused: {why}")
            return False, f"hand-eye calibration failed: {why}"

        if self.poses is None:
            return refuse("no robot poses: set robot_pose_topic")
        with_pose = sum(p is not None for p in robot_poses)
        if with_pose < 3:
            return refuse(f"only {with_pose} of {len(views)} view(s) have a robot pose; need 3 or more "
                          f"(robot poses received on {self.resolve_topic_name(self.pose_topic)}: "
                          f"{self.poses.received}{'; ' + self.pose_error if self.pose_error else ''})")
        try:
            from ..calibrate.handeye import HandEyeError, HandEyeOptions, calibrate_hand_eye
            from ..io.hand_eye_yaml import write_hand_eye_yaml
        except ImportError as e:
            return refuse(f"the hand-eye solver is not available ({e})")
        try:
            he_opts = HandEyeOptions(mode, arm_accuracy_mm=float(self.p("arm_accuracy_mm")),
                                     arm_accuracy_length=float(self.p("arm_accuracy_length")))
            he = calibrate_hand_eye(views, robot_poses, target, mode, opts, he_opts)
        except HandEyeError as e:
            return refuse(str(e))
        except CalibrationError as e:
            return refuse(str(e))
        except Exception as e:  # never let a numerical failure take the node down
            self.get_logger().error(f"hand-eye calibration crashed: {type(e).__name__}: {e}")
            return refuse(f"{type(e).__name__}: {e}")
        doubts = hand_eye_doubts(he)
        if doubts:
            return refuse("the transform is not determined well enough: " + "; ".join(doubts)
                          + " (add views with larger rotations about different axes)")
        dt = time.perf_counter() - t0
        res = he.calibration
        base, tool, cam_frame = (str(self.p("robot_base_frame")), str(self.p("robot_tool_frame")),
                                 str(self.p("camera_frame")))
        parent, target_frame = (tool, base) if mode == "eye_in_hand" else (base, tool)
        info = camera_info_msg(res, str(self.p("camera_name")), self._header())
        path = self._write_outputs(res, views, he)
        he_path = (path.parent / f"{self.p('camera_name')}_hand_eye.yaml"
                   if path.parent == Path.home() / ".ros" / "camera_info" else path.parent / "hand_eye.yaml")
        try:
            write_hand_eye_yaml(he_path, he, parent, cam_frame, target_frame)
        except OSError as e:
            return refuse(f"cannot write {he_path}: {e}")
        X = he.hand_eye
        from geometry_msgs.msg import TransformStamped

        tf = TransformStamped(header=Header(stamp=self.get_clock().now().to_msg(), frame_id=parent),
                              child_frame_id=cam_frame)
        tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = (
            float(v) for v in X.translation)
        q = X.quat
        r = tf.transform.rotation
        r.x, r.y, r.z, r.w = (float(v) for v in q)
        line = (f"hand_eye {mode}: {parent} -> {cam_frame} t=[{', '.join(f'{v:.5f}' for v in X.translation)}] m "
                f"std=[{', '.join(f'{v:.3f}' for v in he.translation_std_mm)}] mm "
                f"(arm accuracy share [{', '.join(f'{v:.3f}' for v in he.arm_share_mm)}] mm) "
                f"q=[{', '.join(f'{v:.6f}' for v in q)}] "
                f"rot_std=[{', '.join(f'{v:.4f}' for v in he.rotation_std_deg)}] deg "
                f"views_used={he.views_used}/{len(views)} rms={he.rms_px:.3f}px "
                f"robot_error={he.robot_error_mm:.3f}mm/{he.robot_error_deg:.4f}deg yaml={he_path}")
        with self.lock:
            self.result, self.result_msg = res, info
            self.hand_eye_line = line
        self.pub_info.publish(info)
        self.pub_hand_eye.publish(tf)
        summary = f"{line}; camera: {res.summary_line()} time={dt:.2f}s yaml={path}; {res.projection_line()}"
        warnings = list(dict.fromkeys([*res.warnings, *he.warnings]))
        if warnings:
            summary += " warnings: " + "; ".join(warnings)
        self.get_logger().info(f"calibrated: {summary}")
        self.publish_status()
        return True, summary

    def _write_outputs(self, res: CalibrationResult, views: list[Detection], hand_eye: Any = None) -> Path:
        name = str(self.p("camera_name"))
        out_dir = str(self.p("output_dir"))
        path_s = str(self.p("calibration_file"))
        if path_s:
            path = Path(path_s).expanduser()
        elif out_dir:
            path = Path(out_dir) / f"{name}.yaml"
        else:
            path = Path.home() / ".ros" / "camera_info" / f"{name}.yaml"
        write_camera_yaml(path, CameraInfoData(res.width, res.height, name, res.K, res.D, res.model,
                                               P=rectified_projection(res.camera())))
        if out_dir:
            summary = {"summary": res.summary_line(), "K": res.K.tolist(), "D": res.D.tolist(), "std": res.std,
                       "rms": res.rms, "degeneracy_ratio": res.degeneracy_ratio, "warnings": res.warnings,
                       "target_shape": res.shape, "target_shape_std": res.shape_std,
                       "views": [{"name": v.name, "used": v.used, "reason": v.reason, "rms": v.rms}
                                 for v in res.views]}
            Path(out_dir).mkdir(parents=True, exist_ok=True)
            (Path(out_dir) / "calibration.json").write_text(json.dumps(summary, indent=1, default=float))
            try:
                from ..report.pages import write_report

                frames = Path(out_dir) / "frames"
                write_report(res, views, out_dir, images=lambda name: read_grey(frames / f"{name}.png")
                             if (frames / f"{name}.png").exists() else None, hand_eye=hand_eye)
            except Exception as e:  # a report must never cost the calibration
                self.get_logger().warn(f"report not written: {type(e).__name__}: {e}")
        return path

    def _srv_calibrate(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        resp.success, resp.message = self.run_calibration()
        return resp

    def _srv_capture(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        timeout = float(self.p("capture_timeout"))
        capture = self.captures.open(timeout)
        if capture is None:
            resp.success, resp.message = False, "a capture is already waiting for a still frame; try again"
            return resp
        resp.success, resp.message = self.captures.wait(capture, timeout)
        if resp.success:
            self.get_logger().info(f"capture: {resp.message}")
        else:
            self.get_logger().warn(f"capture: {resp.message}")
        self.publish_status()
        return resp

    # -- robot poses ----------------------------------------------------------------------------
    def _ensure_pose_subscription(self) -> None:
        """Subscribe to robot_pose_topic once a publisher shows its type (PoseStamped or
        TransformStamped); any other type is refused with the reason in the log and status."""
        if self.pose_sub is not None or not self.pose_topic:
            return
        name = self.resolve_topic_name(self.pose_topic)
        types = dict(self.get_topic_names_and_types()).get(name, [])
        if not types:
            return
        if POSE_STAMPED in types:
            from geometry_msgs.msg import PoseStamped as msg_type
            self.pose_type = POSE_STAMPED
        elif TRANSFORM_STAMPED in types:
            from geometry_msgs.msg import TransformStamped as msg_type
            self.pose_type = TRANSFORM_STAMPED
        else:
            error = (f"robot_pose_topic {name} has type {', '.join(types)}; expected {POSE_STAMPED} or "
                     f"{TRANSFORM_STAMPED}: no robot poses")
            if error != self.pose_error:
                self.pose_error = error
                self.get_logger().error(error)
            return
        infos = self.get_publishers_info_by_topic(name)
        best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
        qos = QoSProfile(depth=200, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE)
        self.pose_sub = self.create_subscription(msg_type, self.pose_topic, self._on_pose, qos,
                                                 callback_group=self._pose_group)
        self.pose_error = ""
        self.get_logger().info(f"robot poses: subscribed to {name} ({self.pose_type}, "
                               f"{'best-effort' if best_effort else 'reliable'})")

    def _on_pose(self, msg: Any) -> None:
        base, tool = str(self.p("robot_base_frame")), str(self.p("robot_tool_frame"))
        fid = msg.header.frame_id.lstrip("/")
        child = getattr(msg, "child_frame_id", "").lstrip("/")
        if (fid and fid != base) or (child and child != tool):
            self.poses_ignored += 1
            got = f"{fid or '?'} -> {child}" if child else f"frame {fid}"
            self.pose_error = (f"robot poses on {self.resolve_topic_name(self.pose_topic)} are {got}, expected "
                               f"{base}{' -> ' + tool if child else ''} (robot_base_frame / robot_tool_frame): "
                               "ignored")
            self.get_logger().warn(self.pose_error, throttle_duration_sec=5.0)
            return
        try:
            if hasattr(msg, "pose"):
                t, q = msg.pose.position, msg.pose.orientation
            else:
                t, q = msg.transform.translation, msg.transform.rotation
            T = Transform.from_quat((q.x, q.y, q.z, q.w), (t.x, t.y, t.z))
        except TransformError as e:
            self.poses_ignored += 1
            self.pose_error = f"robot pose ignored: {e}"
            self.get_logger().warn(self.pose_error, throttle_duration_sec=5.0)
            return
        if self.pose_error.startswith("robot pose"):  # the poses are usable again
            self.pose_error = ""
        if self.poses is not None:
            self.poses.add(int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec), T)

    def _srv_reset(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        with self.lock:
            n = self.collector.clear()
            self.footprints.clear()
            self.auto_done_at = -1
        with self._pending_cv:
            self._session_start = (self.frames_received, self.frames_dropped)
        running = " (a running calibration finishes on its own copy of the views)" if self.calibrating.locked() else ""
        resp.success, resp.message = True, f"cleared {n} view(s){running}; the last result is kept"
        self.get_logger().info(resp.message)
        self.publish_status()
        return resp

    def _srv_commit(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        with self.lock:
            info = self.result_msg
        service = self.set_info_client.srv_name
        if info is None:
            resp.success, resp.message = False, "no calibration to commit: call ~/calibrate first"
            return resp
        if not self.set_info_client.wait_for_service(timeout_sec=2.0):
            resp.success, resp.message = False, f"driver service {service} is not available"
            self.get_logger().warn(resp.message)
            return resp
        done = threading.Event()
        fut = self.set_info_client.call_async(SetCameraInfo.Request(camera_info=info))
        fut.add_done_callback(lambda _f: done.set())
        if not done.wait(10.0):
            fut.cancel()
            resp.success, resp.message = False, f"driver service {service} did not answer within 10 s"
            return resp
        try:
            answer = fut.result()
        except Exception as e:
            resp.success, resp.message = False, f"driver service {service} failed: {e}"
            return resp
        if answer is None:
            resp.success, resp.message = False, f"driver service {service} gave no answer"
            return resp
        resp.success = bool(answer.success)
        resp.message = (f"driver accepted the calibration: {answer.status_message}" if answer.success
                        else f"driver refused the calibration: {answer.status_message}")
        self.get_logger().info(resp.message)
        return resp

    def stop(self) -> None:
        """Stop the detector thread (called before the node is destroyed)."""
        self._stop.set()
        with self._pending_cv:
            self._pending_cv.notify_all()
        if self._worker.is_alive():
            self._worker.join(timeout=5.0)


def main(args: list[str] | None = None) -> int:
    from .spin import run_node

    return run_node(CalibrationNode, (PascalCalibError,), "pascal_calib",
                    lambda: MultiThreadedExecutor(num_threads=6), args)


if __name__ == "__main__":
    raise SystemExit(main())
