"""The calibration node's guide (issue 24): the person guide's hooks (``guide:=true``; the policy is
:mod:`..session.guided_live`, the drawing :mod:`..session.guide_overlay`), ``~/skip_suggestion``,
and ``~/suggest`` for a script: with ``hand_eye`` the next tool poses (latched
``~/suggested_tool_poses``, geometry_msgs/PoseArray in ``robot_base_frame``, ranked best first, and
``~/suggested_tool_pose``, the best, PoseStamped), without it the next camera_T_target, both from
:mod:`..workflows.suggest` on the node's stored views (and their tool poses); an arm's call starts
from the previous call's estimate (:class:`~..workflows.suggest.WarmArmSuggestions`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.callback_groups import CallbackGroup, MutuallyExclusiveCallbackGroup
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.service import Service
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from ..calibrate import CalibrationOptions
from ..detect import Detection
from ..errors import PascalCalibError
from ..geometry import Camera, Placement
from ..io import Suggestions, read_calibration_file
from ..modes import HandEyeMode
from ..session import Answer, GuidedLive, GuideView, LiveSession, draw_guide
from ..targets import Target
from ..workflows import SuggestOptions, WarmArmSuggestions, suggest_for_person
from .conversions import tool_poses_msg
from .guard import guarded_service
from .node_parts import NodeCore
from .robot_poses import RobotPoseInput


class GuidedNode(NodeCore, Protocol):
    """What the guide uses of the node (:class:`.calibration_node.CalibrationNode`): the target, the
    stored views and their robot poses, the calibration file, its publishers and services."""

    target: Target
    session: LiveSession
    robot: RobotPoseInput | None

    @property
    def method(self) -> str: ...

    def calibration_path(self) -> Path: ...

    def publish_status(self) -> None: ...

    def log(self, message: str, ok: bool) -> None: ...

    def _header(self) -> Header: ...

    def resolve_topic_name(self, topic: str) -> str: ...

    def create_publisher(self, msg_type: Any, topic: str, qos_profile: QoSProfile | int) -> Publisher: ...

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable[[Any, Any], Any], *,
                       callback_group: CallbackGroup | None = None) -> Service: ...


def _vec(v: list[float], digits: int = 4) -> str:
    return "[" + ", ".join(f"{x:.{digits}f}" for x in v) + "]"


def arm_answer(s: Suggestions, topic: str) -> str:
    """``~/suggest``'s answer for an arm: the best tool pose and the figures now and predicted."""
    arm = s.arm
    assert arm is not None, "an arm's suggestions"
    now = (f"now sigma {s.projection_sigma_px:.4f} px (goal {s.goal_sigma_px:g}), hand-eye "
           f"{arm.sigma_deg:.5f} deg {arm.sigma_mm:.4f} mm (goals {arm.goal_deg:g} deg {arm.goal_mm:g} mm) from "
           f"{s.views_used} views")
    head = "done: the views reach the goals; call ~/calibrate" if s.done else "next"
    best = s.first
    if best is None or best.tool is None:
        return f"{head}; {now}"
    tool = best.tool
    return (f"{head}: tool t={_vec(list(tool.pose.translation))} m q={_vec(list(tool.pose.quat), 6)} in "
            f"{arm.frame_id}: predicted sigma {best.predicted_sigma_px:.4f} px, hand-eye "
            f"{tool.predicted_sigma_deg:.5f} deg {tool.predicted_sigma_mm:.4f} mm; {now}; "
            f"{len(s.suggestions)} ranked on {topic}")


def person_answer(s: Suggestions) -> str:
    """``~/suggest``'s answer without an arm: the best camera_T_target and the figures."""
    now = f"now sigma {s.projection_sigma_px:.4f} px (goal {s.goal_sigma_px:g}) from {s.views_used} views"
    head = "done: the views reach the goal; call ~/calibrate" if s.done else "next"
    best = s.first
    if best is None:
        return f"{head}; {now}"
    p, T = best.placement, best.camera_T_target
    return (f"{head}: camera_T_target t={_vec(list(T.translation))} m q={_vec(list(T.quat), 6)} (centre at "
            f"({p.pixel[0]:.0f}, {p.pixel[1]:.0f}) px, {p.distance:.2f} m, tilt {p.tilt_deg:.0f} deg): predicted "
            f"sigma {best.predicted_sigma_px:.4f} px; {now}")


def previous_camera(node: GuidedNode) -> Camera | None:
    """The camera of the node's calibration file (``calibration_file``, else where ``~/calibrate``
    writes it), if one is there: the guide draws its first views with it instead of a nominal
    camera (focal = image width). An unreadable file (a field missing or null, not a calibration) is
    logged with the reason and left alone: the guide runs without it."""
    path = node.calibration_path()
    try:
        if not path.exists():
            return None
        cam = read_calibration_file(path).camera
    except Exception as e:  # whatever the file holds, the node starts
        why = str(e) if isinstance(e, PascalCalibError) else f"{path}: {type(e).__name__}: {e}"
        node.get_logger().warning(f"guide: {why}; the first views are drawn with a nominal camera")
        return None
    node.get_logger().info(f"guide: the first views are drawn with the camera of {path} "
                           f"({cam.width}x{cam.height}, fx {cam.K[0, 0]:.1f} px)")
    return cam


class NodeGuide:
    """The guide's interfaces on ``node`` (module docstring); the person guide only with ``guide``."""

    def __init__(self, node: GuidedNode, services: Any, latched: Any) -> None:
        """``services``: the callback group of the node's quick services; ``latched``: its reliable,
        transient-local QoS."""
        self.node = node
        self.live: GuidedLive | None = None
        if node.p("guide"):
            opts = CalibrationOptions(method=node.method, distortion=str(node.p("distortion_model")),
                                      zero_skew=bool(node.p("zero_skew")))
            self.live = GuidedLive(node.target, opts, float(node.p("goal_sigma_px")), int(node.p("suggest_count")),
                                   camera_guess=previous_camera(node), watch_refusals=node.p("collect") == "auto")
        self.arm = WarmArmSuggestions()  # ~/suggest for an arm: each call starts from the previous call's estimate
        self.pub_poses = node.create_publisher(PoseArray, "~/suggested_tool_poses", latched)
        self.pub_pose = node.create_publisher(PoseStamped, "~/suggested_tool_pose", latched)
        self.last_seconds = float("nan")
        self._refusals = self._capture_refusals()  # refused captures seen (count, rejections)
        self._offered: Placement | None = None  # the last ~/suggest's first suggestion
        self._offered_at = (0, 0)  # (refused captures, stored views) when it was offered
        self.avoid: list[Placement] = []  # ~/suggest's refused suggestions (until ~/reset)
        self.suggest_refused = ""
        node.create_service(Trigger, "~/suggest", guarded_service(node, "~/suggest", self._srv_suggest),
                            callback_group=MutuallyExclusiveCallbackGroup())
        node.create_service(Trigger, "~/skip_suggestion", guarded_service(node, "~/skip_suggestion", self._srv_skip),
                            callback_group=services)

    # -- refused captures ---------------------------------------------------------------------
    def _capture_refusals(self) -> tuple[int, int]:
        """(refused captures, frames rejected) of the session so far."""
        session = self.node.session
        with session.lock:
            rejected = sum(session.collector.rejected.values())
        return session.captures.refused, rejected

    def refused_capture(self) -> str:
        """The detector's reason when a capture was refused since the last look ("" if none was, or
        it was refused for motion, a missing pose or a timeout)."""
        now = self._capture_refusals()
        before, self._refusals = self._refusals, now
        if now[0] <= before[0] or now[1] <= before[1]:
            return ""
        with self.node.session.lock:
            why = self.node.session.collector.last_rejection
        return why.message if why is not None and why.kind.is_the_view else ""

    # -- the person guide's hooks (the detector thread) ------------------------------------
    def examine(self, det: Detection) -> Answer | None:
        """The guide's verdict for :meth:`..session.live.LiveSession.examine` (None: no guide)."""
        if self.live is None:
            return None
        why = self.refused_capture()
        if why:
            line = self.live.refuse(why)
            if line:
                self.node.get_logger().warning(f"guide: the captured view was {line}")
        v = self.live.examine(det)
        return Answer(v.store, v.line)

    def stored(self, views: list[Detection]) -> None:
        if self.live is not None:
            self.live.stored(views)

    def draw(self, picture: np.ndarray, width: int) -> np.ndarray:
        return picture if self.live is None else draw_guide(picture, self.live.view(), width)

    def view(self) -> GuideView | None:
        return None if self.live is None else self.live.view()

    def reset(self) -> None:
        """Forget the session's suggestions: the latched ``~/suggested_tool_poses`` becomes an empty
        array (a late subscriber must not drive the arm to a pose of the cleared session)."""
        if self.node.p("hand_eye"):
            header = self.node._header()
            header.frame_id = str(self.node.p("robot_base_frame"))
            self.pub_poses.publish(PoseArray(header=header, poses=[]))
        self.arm.reset()
        self.avoid, self._offered, self.suggest_refused = [], None, ""
        self._refusals = self._capture_refusals()  # the session was cleared first: refusals before are not held
        if self.live is not None:
            self.live.reset()

    def set_goal(self, goal: float) -> None:
        if self.live is not None:
            self.live.set_goal(goal)

    def status(self) -> dict[str, Any]:
        """The guide's lines of ``~/status`` (empty without a guide)."""
        v = self.view()
        out: dict[str, Any] = {}
        if v is not None:
            out = {"guide_sigma_px": round(v.sigma_px, 5), "guide_goal_sigma_px": v.goal_sigma_px,
                   "guide_done": v.done, "guide_computing": v.computing, "guide_suggestion": v.suggestion,
                   "guide_predicted_sigma_px": round(v.predicted_sigma_px, 5),
                   "guide_camera_T_target": _vec([*v.pose.translation, *v.pose.quat], 6) if v.pose else "",
                   "guide_match": round(v.overlap, 3),
                   "guide_matched": v.matched, "guide_hint": v.hint, "guide_error": v.error,
                   "guide_update_s": round(v.update_seconds, 3), "guide_refused": v.refused,
                   "guide_avoided": v.avoided}
        if self.avoid:
            out["suggest_avoided"], out["suggest_refused"] = len(self.avoid), self.suggest_refused
        if np.isfinite(self.last_seconds):
            out["suggest_s"] = round(self.last_seconds, 3)
        return out

    # -- services ---------------------------------------------------------------------------
    def _srv_skip(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        if self.live is None:
            resp.success, resp.message = False, "no guide: start the node with guide:=true"
            return resp
        now = self.live.skip()
        resp.success = bool(now)
        resp.message = f"next view {now}" if now else "no suggestion yet: show the target to the camera first"
        self.node.publish_status()
        return resp

    def _srv_suggest(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        t0 = time.perf_counter()
        try:
            resp.success, resp.message = True, self.suggest()
        except PascalCalibError as e:
            resp.success, resp.message = False, f"no suggestion: {e}"
        except Exception as e:  # a numerical failure must never take the node down
            self.node.get_logger().error(f"suggest crashed: {type(e).__name__}: {e}")
            resp.success, resp.message = False, f"no suggestion: {type(e).__name__}: {e}"
        self.last_seconds = time.perf_counter() - t0
        self.node.log(f"suggest ({self.last_seconds:.2f} s): {resp.message}", resp.success)
        return resp

    def options(self) -> SuggestOptions:
        p = self.node.p
        return SuggestOptions(n=int(p("suggest_count")), goal_sigma_px=float(p("goal_sigma_px")),
                              distortion=str(p("distortion_model")),
                              mode=HandEyeMode(p("hand_eye")) if p("hand_eye") else None,
                              reach=float(p("suggest_reach")), max_turn=float(p("suggest_max_turn")),
                              goal_deg=float(p("goal_hand_eye_deg")), goal_mm=float(p("goal_hand_eye_mm")))

    def _avoid_refused(self, n_views: int) -> str:
        """When the view taken at the last ``~/suggest``'s first suggestion was refused (a refused
        capture since, no view stored): avoid that suggestion; returns the answer's note."""
        refused = self.node.session.captures.refused
        if self._offered is None or refused <= self._offered_at[0] or n_views != self._offered_at[1]:
            return ""
        with self.node.session.lock:
            why = str(self.node.session.collector.last_rejection or "refused")
        p, self._offered = self._offered, None
        self.avoid.append(p)
        self.suggest_refused = (f"the view at the last suggestion (centre at ({p.pixel[0]:.0f}, {p.pixel[1]:.0f}) px, "
                                f"{p.distance:.2f} m, tilt {p.tilt_deg:.0f} deg) was refused ({why}): its "
                                f"neighbourhood is not suggested again ({len(self.avoid)} avoided)")
        return f"; {self.suggest_refused}"

    def _offer(self, s: Suggestions, n_views: int) -> Suggestions:
        """Remember the first suggestion of ``s`` (what a refused capture is held against)."""
        self._offered = s.first.placement if s.first is not None and not s.done else None
        self._offered_at = (self.node.session.captures.refused, n_views)
        return s

    def suggest(self) -> str:
        """The answer of ``~/suggest``; a :class:`~..errors.PascalCalibError` says why there is none."""
        node, opt = self.node, self.options()
        snap = node.session.snapshot()
        note = self._avoid_refused(len(snap.views))
        if opt.mode is None:
            found = self._offer(suggest_for_person(snap.views, node.target, opt, self.avoid), len(snap.views))
            return person_answer(found) + note
        if node.robot is None:
            raise PascalCalibError("hand_eye is set but there are no robot poses: set robot_pose_topic")
        if sum(p is not None for p in snap.robot_poses) == 0:
            raise PascalCalibError(f"none of the {len(snap.views)} stored view(s) has a robot pose (poses received "
                                   f"on {node.robot.resolved}: {node.robot.poses.received}); capture views at "
                                   "three or more arm poses first")
        base, tool = str(node.p("robot_base_frame")), str(node.p("robot_tool_frame"))
        found = self._offer(self.arm.suggest(snap.views, snap.robot_poses, node.target, opt, (base, tool),
                                             self.avoid), len(snap.views))
        if not found.suggestions and not found.done:
            raise PascalCalibError(f"no candidate view inside the trust region (suggest_reach {opt.reach:g} m, "
                                   f"suggest_max_turn {opt.max_turn:g} deg around the visited tool poses); widen it"
                                   f" or capture views at more varied poses; {arm_answer(found, '')}")
        if found.suggestions:
            header = node._header()
            header.frame_id = base
            arr = tool_poses_msg(found, header)
            self.pub_poses.publish(arr)
            self.pub_pose.publish(PoseStamped(header=header, pose=arr.poses[0]))
        return arm_answer(found, node.resolve_topic_name("~/suggested_tool_poses")) + note
