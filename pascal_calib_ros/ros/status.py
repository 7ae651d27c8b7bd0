"""``~/status`` of the calibration node: the live session's counts and coverage, the frames received,
examined and dropped, the robot poses, the last result, hand-eye and verification."""

from __future__ import annotations

import threading
from typing import Protocol

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header

from ..calibrate import CalibrationResult
from ..report import summary_line
from ..session import LiveSession
from .guide_services import NodeGuide
from .node_parts import NodeCore
from .node_session import NodeSession
from .robot_poses import RobotPoseInput
from .tf_static import StaticTransforms


class StatusNode(NodeCore, Protocol):
    """What ``~/status`` reads of the node (:class:`.calibration_node.CalibrationNode`)."""

    session: LiveSession
    result: CalibrationResult | None
    robot: RobotPoseInput | None
    calibrating: threading.Lock
    frames_received: int
    frames_examined: int
    frames_dropped: int
    frames_bad: int
    last_error: str
    hand_eye_line: str
    verify_line: str
    tf_static: StaticTransforms
    recording: NodeSession
    guide: NodeGuide

    def get_name(self) -> str: ...

    def session_frames(self) -> tuple[int, int]: ...

    def dropped_note(self) -> str: ...

    def _header(self) -> Header: ...


def status_message(node: StatusNode) -> DiagnosticArray:
    """The node's status now (one DiagnosticStatus with key-values; README of the node's page)."""
    s = node.session
    with s.lock:
        col = s.collector
        cov, n, ready = col.coverage(), len(col.views), col.ready
        rejected, last_rej = dict(col.rejected), str(col.last_rejection or "")
        with_pose = sum(p is not None for p in col.robot_poses)
    result = node.result
    _, session_dropped = node.session_frames()
    pose_error = node.robot.error if node.robot is not None else ""
    st = DiagnosticStatus(name=f"{node.get_name()}: calibration", hardware_id=str(node.p("camera_name")))
    if node.calibrating.locked():
        st.level, st.message = DiagnosticStatus.OK, "calibrating"
    elif pose_error:
        st.level, st.message = DiagnosticStatus.ERROR, pose_error
    elif ready:
        st.level, st.message = DiagnosticStatus.OK, f"ready: {n} views; call ~/calibrate"
    else:
        st.level = DiagnosticStatus.WARN
        st.message = (f"collecting: {n}/{col.min_views} views, coverage "
                      + " ".join(f"{k} {v:.2f}" for k, v in cov.items()))
        if session_dropped:
            st.message += (f"; {session_dropped} frame(s) dropped while the detector was busy "
                           "(replay: use lock-step or a lower rate)")
    kv = {
        "views_accepted": n, "views_rejected": sum(rejected.values()), "ready": ready,
        "frames_received": node.frames_received, "frames_examined": node.frames_examined,
        "frames_dropped": node.frames_dropped, "frames_dropped_session": session_dropped,
        "frames_bad": node.frames_bad, "last_rejection": last_rej,
        "last_error": node.last_error,
        "frames_dropped_note": node.dropped_note(),
        **{f"coverage_{k}": round(v, 3) for k, v in cov.items()},
        **{f"rejected: {k}": v for k, v in sorted(rejected.items())},
        "result": summary_line(result) if result else "",
        "collect": node.p("collect"), "max_motion_px": s.gate.max_motion_px,
        "captures_stored": s.captures.stored, "captures_refused": s.captures.refused,
    }
    if node.robot is not None:
        kv.update(node.robot.status(with_pose))
    if node.p("hand_eye"):
        kv["hand_eye"] = node.hand_eye_line
        kv["tf_static"] = node.tf_static.describe()
    kv.update(node.recording.status())
    kv["verify"] = node.verify_line
    kv.update(node.guide.status())
    st.values = [KeyValue(key=k, value=str(v)) for k, v in kv.items()]
    return DiagnosticArray(header=node._header(), status=[st])

