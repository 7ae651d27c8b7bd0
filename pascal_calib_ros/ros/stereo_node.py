"""The calibration node's stereo mode (``calibration_node --ros-args -p mode:=stereo``), node name
``pascal_calib``.

Subscribes ``left/image`` and ``right/image`` (or ``left/image/compressed`` and
``right/image/compressed`` with ``transport:=compressed``), each with the QoS its publisher needs
(:mod:`.image_subscription`), pairs the frames by header stamp within ``sync_slop`` seconds
(:mod:`..session.frame_pairing`; frames that never pair are counted and ``~/status`` says why),
detects the target in both frames of the newest pair in a worker thread (older pairs are dropped
and counted, as the mono node drops frames), and hands the detections to the stereo session
(:mod:`..session.stereo_live`). Every frame the node is done with (examined in a pair, or dropped
because it cannot pair) is acknowledged on ``~/examined_frames`` for ``replay_node``'s lock-step.

``~/calibrate`` runs the CLI's stereo workflow on the stored shots (:mod:`..workflows.
stereo_session`) in a service thread, and only a checked result is published: ``~/left/
camera_info`` and ``~/right/camera_info`` (K, D, R = the rectification rotation, P = the
rectified projection, the right camera's ``P[0,3] = -fx' * baseline``; reliable, transient
local) and ``~/stereo_transform`` (geometry_msgs/TransformStamped, latched: the right optical
frame's pose in the left's, header ``left_frame``, child ``right_frame``; it carries
``X_left = R' X_right + t'``, the inverse of stereo.yaml's ``X_right = R X_left + T``; the same
transform on ``/tf_static``, :mod:`.tf_static`), and written (left.yaml, right.yaml, stereo.yaml, the
calibration records). ``~/commit`` sends each camera's CameraInfo to its own driver's
``set_camera_info`` service and reports both answers.

Every stored shot is recorded as it is taken (``record_session``, :class:`.node_session.
StereoNodeSession`): both frames, then the session file naming the shot, its stamps and which
camera's view was not used; ``resume:=true`` detects the recorded shots again and stores them
before the first new pair (``pascal-calib stereo SESSION`` calibrates the folder offline).
"""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, KeyValue
from geometry_msgs.msg import TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from sensor_msgs.srv import SetCameraInfo
from std_msgs.msg import Header

from ..calibrate import CalibrationError, CalibrationOptions
from ..detect import detect_target
from ..errors import PascalCalibError
from ..io import FileWriteError, ImageConversionError, compressed_to_grey, image_to_grey
from ..session import (
    NOT_WRITTEN,
    SIDES,
    Answer,
    ApproximatePairer,
    Dropped,
    StereoSession,
    max_motion_of,
    placement_points,
)
from ..workflows import (
    ResultStore,
    StereoOutcome,
    StereoSessionOptions,
    answer_line,
    calibrate_stereo_session,
    detection_params,
    stereo_output_dir,
    write_session_report,
)
from .commit import commit_pair
from .conversions import camera_info_msg, image_msg, transform_msg
from .guard import guarded_callback, save_frame
from .image_subscription import MatchedImageSubscription
from .node_base import LATCHED, CalibrationNodeBase
from .node_session import StereoNodeSession
from .params import ParameterError
from .stereo_status import stereo_status_message
from .tf_static import StaticTransforms


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec)


class StereoCalibrationNode(CalibrationNodeBase):
    MODE = "stereo"
    input_name = "pair"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.session = StereoSession(self.p("min_views"), self.p("max_views"), self.p("min_view_distance"),
                                     max_motion_of(float(self.p("max_motion_px")), "auto", False),
                                     board_points=placement_points(self.target))
        self.pairer = ApproximatePairer(float(self.p("sync_slop")))
        self.outcome: StereoOutcome | None = None
        self.info_msgs: tuple[CameraInfo, CameraInfo] | None = None
        self.result_line = self.report_note = ""
        self.frame_ids = ["", ""]
        self.frames_bad = [0, 0]
        self.frames_not_saved = 0  # stored frames output_dir could not take (save_frame)
        self.pairs_examined = self.pairs_dropped = 0
        self._session_start = 0  # pairs dropped before the last ~/reset
        self.recording = StereoNodeSession(self)  # the session folder; resume:=true stores its shots again
        resumed = self.recording.resume()
        self._create_interfaces()
        self.start()
        topics = ", ".join(f"{s.resolved} ({s.qos_name})" for s in self.subs)
        folder = self.recording.folder
        self.get_logger().info(
            f"stereo: target {self.target.name}, listening on {topics}, pairing stamps within sync_slop "
            f"{float(self.p('sync_slop')):g} s; call {self.resolve_service_name('~/calibrate')} when the status "
            "says ready" + (f"; session folder {folder.path}" + (f" ({resumed} shot(s) resumed)" if resumed else "")
                            if folder is not None else ""))

    def _create_interfaces(self) -> None:
        """Publishers, services, the driver clients and the two image subscriptions (docs/nodes.md)."""
        self.pub_info = (self.create_publisher(CameraInfo, "~/left/camera_info", LATCHED),
                         self.create_publisher(CameraInfo, "~/right/camera_info", LATCHED))
        self.pub_transform = self.create_publisher(TransformStamped, "~/stereo_transform", LATCHED)
        self.tf_static = StaticTransforms(self)  # the rig transform on /tf_static, with ~/stereo_transform
        self.pub_status = self.create_publisher(DiagnosticArray, "~/status", 10)
        self.pub_det = self.create_publisher(Image, "~/detections", 2)
        examined_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                  durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
        self.pub_examined = self.create_publisher(Header, "~/examined_frames", examined_qos)
        services = ReentrantCallbackGroup()
        self.add_services({"calibrate": self.run_calibration, "reset": self.reset, "commit": self.commit}, services)
        self.set_info_clients = (
            self.create_client(SetCameraInfo, self.p("left_set_camera_info_service"), callback_group=services),
            self.create_client(SetCameraInfo, self.p("right_set_camera_info_service"), callback_group=services))
        if self.set_info_clients[0].srv_name == self.set_info_clients[1].srv_name:
            raise ParameterError(f"left_set_camera_info_service and right_set_camera_info_service both resolve to "
                                 f"{self.set_info_clients[0].srv_name}: each camera's driver has its own service")
        compressed = self.p("transport") == "compressed"
        group = MutuallyExclusiveCallbackGroup()  # one pairer: the two image callbacks never run at once
        self.subs = tuple(MatchedImageSubscription(
            self, f"{side}/image/compressed" if compressed else f"{side}/image",
            CompressedImage if compressed else Image, guarded_callback(self, f"{side} image callback",
                                                                       partial(self._on_image, c)),
            lambda: str(self.p("qos")), group) for c, side in enumerate(SIDES))
        self.add_timers({"image subscription check": self._ensure_subscriptions, "status": self.publish_status})

    # -- parameters ------------------------------------------------------------------
    def apply_changes(self, changes: dict[str, Any]) -> None:
        if "target" in changes:
            self.session.clear()
        if "sync_slop" in changes:
            with self._pending_cv:
                self.pairer.set_slop(float(changes["sync_slop"]))
        motion = None
        if "max_motion_px" in changes:
            motion = max_motion_of(float(changes["max_motion_px"]), "auto", False)
        self.session.set_limits(changes.get("min_views"), changes.get("max_views"), changes.get("min_view_distance"),
                                motion)

    # -- image input ------------------------------------------------------------------
    def _ensure_subscriptions(self) -> None:
        for s in self.subs:
            s.ensure()

    def _on_image(self, side: int, msg: Any) -> None:
        """Executor callback: pair by stamp; only the newest pair waits for the detector."""
        with self._pending_cv:
            pairs, dropped = self.pairer.push(side, _stamp_ns(msg), (msg, time.monotonic()))
            for left, right in pairs:
                if self.hand_over((left.item[0], right.item[0], max(left.item[1], right.item[1]))):
                    self.pairs_dropped += 1
        self._acknowledge_dropped(dropped)

    def _acknowledge_dropped(self, dropped: list[Dropped]) -> None:
        for d in dropped:
            self.last_error = f"{SIDES[d.frame.side]} frame not paired: {d.reason}"
            self.get_logger().warn(self.last_error, throttle_duration_sec=5.0)
            self._acknowledge(d.frame.item[0])

    def process(self, pending: Any) -> None:
        self._process(pending[0], pending[1])

    def examined(self, pending: Any) -> None:
        with self._pending_cv:
            self.pairs_examined += 1
        self._acknowledge(pending[0])
        self._acknowledge(pending[1])

    def _acknowledge(self, msg: Any) -> None:
        try:
            self.pub_examined.publish(msg.header)
        except Exception as e:  # shutting down, or a header that cannot be published
            self.get_logger().warn(f"cannot acknowledge frame: {type(e).__name__}: {e}", throttle_duration_sec=5.0)

    def _grey(self, side: int, msg: Any) -> Any:
        try:
            return compressed_to_grey(msg) if isinstance(msg, CompressedImage) else image_to_grey(msg)
        except ImageConversionError as e:
            self.frames_bad[side] += 1
            self.session.bad_frame(side, str(e))
            self.last_error = f"bad {SIDES[side]} frame: {e}"
            self.get_logger().warn(self.last_error, throttle_duration_sec=5.0)
            return None

    def _process(self, left: Any, right: Any) -> None:
        msgs = (left, right)
        imgs = [self._grey(c, m) for c, m in enumerate(msgs)]
        if imgs[0] is None or imgs[1] is None:
            return
        for c, m in enumerate(msgs):
            self.frame_ids[c] = m.header.frame_id or self.frame_ids[c]
        params = detection_params(str(self.p("distortion_model")), float(self.p("gamma")))
        name = f"shot_{self.pairs_examined + self.recording.name_offset:06d}"
        dets = (detect_target(imgs[0], self.target, params, name=name),
                detect_target(imgs[1], self.target, params, name=name))
        stamps = (_stamp_ns(left), _stamp_ns(right))
        out = self.session.examine(dets, stamps, drawing=self.pub_det.get_subscription_count() > 0)
        note = ""
        if out.stored:  # recorded before the pair is acknowledged: a kill after it loses nothing
            not_used = tuple("" if ok else line.removeprefix("not used: ")
                             for ok, line in zip(out.camera_ok, out.camera_lines, strict=True))
            note = self.recording.record_shot(name, (imgs[0], imgs[1]), stamps, (not_used[0], not_used[1]))
            if note.startswith(NOT_WRITTEN):
                self.last_error = note
        if out.stored and self.p("output_dir"):
            for c, side in enumerate(SIDES):  # the CLI's input, and the report's images
                save_frame(self, Path(self.p("output_dir")) / side / f"{name}.png", imgs[c])
        vis = self.session.picture((imgs[0], imgs[1]), dets, out)
        if vis is not None:
            self.pub_det.publish(image_msg(vis, left.header))
        if out.stored:
            self.log(out.why + (f"; {note}" if note else ""), not note.startswith(NOT_WRITTEN))
            self.publish_status()
        self.auto_calibrate(out.ready, out.both)

    # -- status -------------------------------------------------------------------------
    def pairs_dropped_session(self) -> int:
        with self._pending_cv:
            return self.pairs_dropped - self._session_start

    def sync_note(self) -> str:
        """Why frames arrive but never pair (empty while they pair)."""
        with self._pending_cv:
            return self.pairer.stats.never_paired_note(self.pairer.slop_s,
                                                       (self.subs[0].resolved, self.subs[1].resolved))

    def busy_note(self) -> str:
        """What the pairs dropped while the detector was busy mean (empty: none this session)."""
        dropped = self.pairs_dropped_session()
        return (f"{dropped} pair(s) arrived while the detector was busy and were dropped unexamined (only the newest "
                "pair waits). Replaying a recording: use replay_node's lock-step mode; live cameras: hold each pose "
                "longer") if dropped else ""

    def notes(self) -> list[str]:
        """What keeps shots from arriving: frames that never pair, pairs dropped while the detector was busy."""
        return [n for n in (self.sync_note(), self.busy_note()) if n]

    def publish_status(self) -> None:
        msg = stereo_status_message(self)
        msg.status[0].values.extend(KeyValue(key=k, value=str(v)) for k, v in self.recording.folder_status().items())
        self.pub_status.publish(msg)

    def header(self, side: int) -> Header:
        frame = self.frame_ids[side] or str(self.p(f"{SIDES[side]}_frame"))
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=frame)

    # -- calibration ------------------------------------------------------------------------
    def options(self, min_views: int) -> StereoSessionOptions:
        opts = CalibrationOptions(method=self.method, distortion=str(self.p("distortion_model")),
                                  zero_skew=bool(self.p("zero_skew")), min_views=min_views)
        return StereoSessionOptions(opts, float(self.p("alpha")), str(self.p("camera_name")), str(self.p("left_frame")),
                                    str(self.p("right_frame")))

    def _refuse(self, why: str) -> Answer:
        self.get_logger().warn(f"stereo calibration refused: {why}")
        return Answer(False, f"stereo calibration failed: {why}")

    def attempt(self) -> Answer:
        snap = self.session.snapshot()
        if snap.both < snap.min_views:
            return self._refuse(self.session.refusal(snap, self.notes()))
        dets = snap.detections()
        try:
            outcome = calibrate_stereo_session(dets, self.target, self.options(snap.min_views))
        except (CalibrationError, PascalCalibError) as e:
            return self._refuse(f"{e} (nothing published; the previous result stays)")
        out_dir = stereo_output_dir(str(self.p("camera_name")), str(self.p("output_dir")))
        try:  # one result set (:mod:`..workflows.result_set`): a kill never leaves a mixed pair
            rs = ResultStore(out_dir).write(outcome.write)
        except (OSError, FileWriteError) as e:
            return self._refuse(f"cannot write the calibration files in {out_dir}: {e} (nothing published)")
        files = [out_dir / n for n in rs.names]
        self.history.succeeded(rs.id, snap.both)
        self._publish(outcome)
        self.result_line = answer_line(outcome, files)
        self.get_logger().info(f"stereo calibrated: {self.result_line}")
        self.report_note = ""
        if self.p("output_dir"):  # the stored frames are there: the reports, after the result is out
            frames = Path(str(self.p("output_dir")))

            def frame_of(c: int, name: str) -> Path | None:
                p = frames / SIDES[c] / f"{name}.png"
                return p if p.exists() else None

            _, self.report_note = write_session_report(outcome, dets, self.target, frames / "report", frame_of)
            if self.report_note:
                self.get_logger().warn(self.report_note)
        self.publish_status()
        return Answer(True, self.result_line + (f"; {self.report_note}" if self.report_note else ""))

    def _publish(self, outcome: StereoOutcome) -> None:
        infos = outcome.camera_infos()
        msgs = (camera_info_msg(infos[0], self.header(0)), camera_info_msg(infos[1], self.header(1)))
        self.outcome, self.info_msgs = outcome, msgs
        for pub, msg in zip(self.pub_info, msgs, strict=True):
            pub.publish(msg)
        tf = transform_msg(outcome.rig.pose_in_reference(1), str(self.p("left_frame")), str(self.p("right_frame")),
                           self.get_clock().now().to_msg())
        self.pub_transform.publish(tf)
        if not self.tf_static.send(tf):
            self.get_logger().warn(self.tf_static.unavailable, once=True)

    # -- services -------------------------------------------------------------------------
    def reset(self) -> Answer:
        n = self.session.clear()
        self.auto_done_at = -1
        with self._pending_cv:
            self._session_start = self.pairs_dropped
        running = " (a running calibration finishes on its own copy of the shots)" if self.calibrating.locked() else ""
        live = self.history.live
        answer = (f"cleared {n} shot(s){running}; the live {live.describe() if live else 'result: none'} is kept"
                  + self.recording.clear())
        self.get_logger().info(answer)
        self.publish_status()
        return Answer(True, answer)

    def commit(self) -> Answer:
        """``~/commit``: each camera's CameraInfo to its own driver, unless the result is stale."""
        problem = "" if self.info_msgs is None else self.history.commit_problem()
        ok, answer = (False, problem) if problem else commit_pair(self.set_info_clients, self.info_msgs)
        live = self.history.live
        if ok and live is not None:
            answer = f"{live.describe()}: {answer}"
        self.log(f"commit: {answer}", ok)
        return Answer(ok, answer)
