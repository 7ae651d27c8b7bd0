"""``pascal-calib suggest``: from the views captured so far, the next views to take (NEXT.yaml),
for a person holding the target or a script driving a robot arm, until the accuracy asked for is
reached. ROS-free; the node's ``~/suggest`` will call the same functions.

NEXT.yaml::

    done: false                    # the current views reach the goal (the real sigma, never a prediction)
    projection_sigma_px: 0.52      # worst projection sigma over every pixel of the image now
    goal_sigma_px: 0.1
    distance_m: 0.45               # where the sigma is evaluated: the median distance to the target's centre
    views_used: 5
    suggestions:                   # best first
      - camera_T_target:           # the target YAML frame in the camera optical frame: X_cam = R X + t
          translation: [x, y, z]   # metres
          rotation: [qx, qy, qz, qw]
        predicted_sigma_px: 0.21   # the worst projection sigma over the image once this view is added
        placement: {pixel: [u, v], distance_m: 0.4, tilt_deg: 50, tilt_axis_deg: 315, roll_deg: 0}
        tool:                      # with --poses: T_base_tool in POSES.yaml's frames
          translation: [x, y, z]
          rotation: [qx, qy, qz, qw]
        predicted_hand_eye_sigma_deg: 0.02   # with --poses
        predicted_hand_eye_sigma_mm: 0.2

With ``--poses`` also ``mode``, ``frame_id``, ``child_frame_id``, ``hand_eye_sigma_deg`` and
``hand_eye_sigma_mm`` now (sigma of X from the views' information, norms over the axes), their
goals, and ``done`` requires those goals too. With placements to avoid (suggestions whose views the
detector refused) also ``avoided``: their placements; no suggestion is in their neighbourhood.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from threadpoolctl import threadpool_limits

from ..analysis.arm_guidance import DISTINCT_ROLL_DEG, ArmGoals, TrustRegion, arm_model, suggest_arm_views
from ..analysis.candidates import Placement
from ..analysis.guidance import Linearisation, ViewPredictor
from ..analysis.view_ranking import RankedView, distinct_from_all, suggest_views
from ..calibrate.handeye.options import HAND_EYE_MODES, HandEyeOptions
from ..calibrate.handeye.session import calibrate_hand_eye_warm
from ..calibrate.handeye.warm import HandEyeStart
from ..calibrate.options import MIN_VIEWS, CalibrationOptions
from ..calibrate.pipeline import calibrate
from ..calibrate.problem import DISTORTION_MODELS
from ..calibrate.result import CalibrationError
from ..detect.detection import Detection
from ..errors import PascalCalibError
from ..geometry.transform import Transform
from ..targets import Target


class SuggestError(PascalCalibError):
    """The inputs give no suggestion; the message says why and what to do."""


@dataclass(frozen=True)
class SuggestOptions:
    n: int = 5
    goal_sigma_px: float = 0.1
    distortion: str = "plumb_bob"
    mode: str = ""  # "", eye_in_hand or eye_to_hand (with robot poses)
    reach: float = 0.3  # m
    max_turn: float = 120.0  # deg
    goal_deg: float = 0.01  # hand-eye rotation sigma goal (arms)
    goal_mm: float = 0.1  # hand-eye translation sigma goal (arms)

    def problem(self) -> str:
        """Why these options cannot be used ("" if they can)."""
        if self.n < 1:
            return f"-n {self.n}: ask for at least one suggestion"
        for name, v in (("--goal-sigma", self.goal_sigma_px), ("--reach", self.reach), ("--max-turn", self.max_turn),
                        ("--goal-deg", self.goal_deg), ("--goal-mm", self.goal_mm)):
            if not (np.isfinite(v) and v > 0):
                return f"{name} {v}: give a finite value > 0"
        if self.mode and self.mode not in HAND_EYE_MODES:
            return f"--mode {self.mode}: choose one of {', '.join(HAND_EYE_MODES)}"
        if self.distortion not in DISTORTION_MODELS:
            return f"--distortion {self.distortion}: choose one of {', '.join(DISTORTION_MODELS)}"
        return ""


def _pose_doc(T: Transform) -> dict[str, list[float]]:
    return {"translation": [round(float(v), 6) for v in T.translation],
            "rotation": [round(float(v), 7) for v in T.quat]}


def _placement_doc(p: Placement) -> dict[str, Any]:
    return {"pixel": [round(p.pixel[0], 1), round(p.pixel[1], 1)], "distance_m": round(p.distance, 4),
            "tilt_deg": round(p.tilt_deg, 1), "tilt_axis_deg": round(p.axis_deg, 1), "roll_deg": round(p.roll_deg, 1)}


def _view_doc(r: RankedView) -> dict[str, Any]:
    return {"camera_T_target": _pose_doc(r.pose), "predicted_sigma_px": round(r.predicted_sigma_px, 5),
            "placement": _placement_doc(r.placement)}


def placement_of_doc(doc: dict[str, Any]) -> Placement:
    """The :class:`~..analysis.candidates.Placement` of NEXT.yaml's ``placement`` mapping."""
    u, v = (float(x) for x in doc["pixel"])
    return Placement((u, v), float(doc["distance_m"]), float(doc["tilt_deg"]), float(doc["tilt_axis_deg"]),
                     float(doc.get("roll_deg", 0.0)))


def _with_avoided(doc: dict[str, Any], avoid: list[Placement]) -> dict[str, Any]:
    if avoid:
        doc["avoided"] = [_placement_doc(p) for p in avoid]
    return doc


def _usable(dets: list[Detection]) -> int:
    n = sum(d.ok for d in dets)
    if n < MIN_VIEWS:
        raise SuggestError(f"{n} usable view(s); suggestions need at least {MIN_VIEWS} (take views of the whole "
                           "target tilted about 30-40 degrees about different axes, then ask again)")
    return n


def suggest_for_person(dets: list[Detection], target: Target, opt: SuggestOptions,
                       avoid: list[Placement] | None = None) -> dict[str, Any]:
    """NEXT.yaml's document for views without robot poses; none of its suggestions in the
    neighbourhood of a placement of ``avoid`` (views there were refused)."""
    avoid = list(avoid or [])
    _usable(dets)
    try:
        res = calibrate(dets, target, CalibrationOptions(distortion=opt.distortion))
    except CalibrationError as e:
        raise SuggestError(f"the views do not calibrate: {e}") from None
    if res.refinement is None or res.refinement.covariance is None:
        raise SuggestError("the calibration has no covariance to predict from (refinement failed)")
    with threadpool_limits(1, "blas"):  # small dense products: one thread is faster on a shared machine
        s = suggest_views(res.refinement, target, res.width, res.height, opt.n, avoid=avoid)
    return _with_avoided({"done": bool(s.sigma_px <= opt.goal_sigma_px), "projection_sigma_px": round(s.sigma_px, 5),
                          "goal_sigma_px": opt.goal_sigma_px, "distance_m": round(s.distance, 4),
                          "views_used": res.n_used, "suggestions": [_view_doc(r) for r in s.suggestions]}, avoid)


def suggest_for_arm(dets: list[Detection], robot: list[Transform | None], target: Target, opt: SuggestOptions,
                    frames: tuple[str, str], avoid: list[Placement] | None = None) -> dict[str, Any]:
    """NEXT.yaml's document for an arm session (``robot[i]``: T_base_tool of view i, or None)."""
    return arm_suggestions(dets, robot, target, opt, frames, avoid=avoid)[0]


def arm_suggestions(dets: list[Detection], robot: list[Transform | None], target: Target, opt: SuggestOptions,
                    frames: tuple[str, str], start: HandEyeStart | None = None,
                    avoid: list[Placement] | None = None) -> tuple[dict[str, Any], HandEyeStart]:
    """:func:`suggest_for_arm`'s document, its hand-eye estimate warm from a previous call's ``start``
    where it applies (:mod:`..calibrate.handeye.warm`: the same estimate to the solves' tolerance;
    "done" from the projection sigma of these views), and the start of the next call. ``avoid``:
    placements whose views were refused; the ranking is asked for more views and those in their
    neighbourhood (not distinct, the arm's roll counted) are left out."""
    avoid = list(avoid or [])
    _usable([d for d, r in zip(dets, robot, strict=True) if r is not None])
    try:
        # the jackknife's sigmas of X are not what the prediction uses (it builds its own from the
        # views' information and the arm's estimated accuracy): off, a third of the time at 20 views
        h, nxt = calibrate_hand_eye_warm(dets, robot, target, opt.mode, CalibrationOptions(distortion=opt.distortion),
                                         HandEyeOptions(mode=opt.mode, jackknife_groups=0), start)
    except CalibrationError as e:  # HandEyeError included
        raise SuggestError(f"the views do not calibrate: {e}") from None
    ref = h.calibration.refinement
    if ref is None or ref.covariance is None:
        raise SuggestError("the calibration has no covariance to predict from (refinement failed)")
    used = [k for k, v in enumerate(h.per_view) if v.used]
    poses = [robot[k] for k in used]
    assert all(p is not None for p in poses)
    w, hgt = h.calibration.width, h.calibration.height
    with threadpool_limits(1, "blas"):
        intrinsic = ViewPredictor(Linearisation.of_refinement(ref), w, hgt)
        model = arm_model(h, poses, target, intrinsic.noise, w, hgt)  # type: ignore[arg-type]
        trust = TrustRegion(tuple(poses), opt.reach, opt.max_turn)  # type: ignore[arg-type]
        s = suggest_arm_views(model, target, trust, opt.n + 3 * len(avoid),
                              ArmGoals(opt.goal_sigma_px, opt.goal_deg, opt.goal_mm))
        sigma = intrinsic.sigma_now()
    kept = s.suggestions
    if avoid and kept:
        new = distinct_from_all([a.view.placement for a in kept], avoid, w, hgt, DISTINCT_ROLL_DEG)
        kept = [a for a, k in zip(kept, new, strict=True) if k]
    kept = kept[:opt.n]
    done = sigma <= opt.goal_sigma_px and s.rotation_deg <= opt.goal_deg and s.translation_mm <= opt.goal_mm
    sugg = []
    for a in kept:
        d = _view_doc(a.view)
        d["tool"] = _pose_doc(a.tool)
        d["predicted_hand_eye_sigma_deg"] = round(a.predicted_rotation_deg, 6)
        d["predicted_hand_eye_sigma_mm"] = round(a.predicted_translation_mm, 5)
        sugg.append(d)
    doc = {"done": bool(done), "projection_sigma_px": round(sigma, 5), "goal_sigma_px": opt.goal_sigma_px,
            "distance_m": round(intrinsic.distance_now, 4), "views_used": len(used), "mode": opt.mode,
            "frame_id": frames[0], "child_frame_id": frames[1], "hand_eye_sigma_deg": round(s.rotation_deg, 6),
            "hand_eye_sigma_mm": round(s.translation_mm, 5), "goal_hand_eye_sigma_deg": opt.goal_deg,
            "goal_hand_eye_sigma_mm": opt.goal_mm, "reach_m": opt.reach, "max_turn_deg": opt.max_turn,
            "suggestions": sugg}
    return _with_avoided(doc, avoid), nxt


class WarmArmSuggestions:
    """:func:`suggest_for_arm` for a session that grows a view at a time (the node's ``~/suggest``
    after every capture): each call starts from the previous call's estimate (:func:`arm_suggestions`);
    a call whose views are not the previous ones plus new ones, or with other options, is cold.
    Thread-safe: calls run one at a time; :meth:`reset` does not wait for a running one (its estimate
    is then not kept)."""

    def __init__(self) -> None:
        self._start: HandEyeStart | None = None
        self._resets = 0
        self._lock = threading.Lock()

    def suggest(self, dets: list[Detection], robot: list[Transform | None], target: Target, opt: SuggestOptions,
                frames: tuple[str, str], avoid: list[Placement] | None = None) -> dict[str, Any]:
        with self._lock:
            resets = self._resets
            doc, nxt = arm_suggestions(dets, robot, target, opt, frames, self._start, avoid)
            if resets == self._resets:
                self._start = nxt
            return doc

    def reset(self) -> None:
        """Forget the previous estimate (the next call is cold)."""
        self._resets += 1
        self._start = None


def write_next_yaml(path: str | Path, doc: dict[str, Any]) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return p


def summary(doc: dict[str, Any]) -> str:
    """Lines for people."""
    lines = [f"projection sigma {doc['projection_sigma_px']:.3f} px (worst over the whole image, at "
             f"{doc['distance_m']:.2f} m; goal {doc['goal_sigma_px']:g} px) from {doc['views_used']} views"]
    if "hand_eye_sigma_deg" in doc:
        lines.append(f"hand-eye sigma {doc['hand_eye_sigma_deg']:.4f} deg, {doc['hand_eye_sigma_mm']:.3f} mm "
                     f"(goals {doc['goal_hand_eye_sigma_deg']:g} deg, {doc['goal_hand_eye_sigma_mm']:g} mm)")
    lines.append("DONE: the views reach the goal" if doc["done"] else "not done yet; next views, best first:")
    for k, s in enumerate(doc["suggestions"], 1):
        p = s["placement"]
        line = (f"  {k}. target centre at pixel ({p['pixel'][0]:.0f}, {p['pixel'][1]:.0f}), {p['distance_m']:.2f} m, "
                f"tilted {p['tilt_deg']:.0f} deg about {p['tilt_axis_deg']:.0f} deg, rolled {p['roll_deg']:.0f}: "
                f"predicted sigma {s['predicted_sigma_px']:.3f} px")
        if "tool" in s:
            line += f", hand-eye {s['predicted_hand_eye_sigma_deg']:.4f} deg {s['predicted_hand_eye_sigma_mm']:.3f} mm"
        lines.append(line)
    for p in doc.get("avoided", []):
        lines.append(f"  avoided (a view there was refused): centre at pixel ({p['pixel'][0]:.0f}, "
                     f"{p['pixel'][1]:.0f}), {p['distance_m']:.2f} m, tilted {p['tilt_deg']:.0f} deg about "
                     f"{p['tilt_axis_deg']:.0f} deg, and its neighbourhood")
    return "\n".join(lines)


__all__ = ["SuggestError", "SuggestOptions", "WarmArmSuggestions", "arm_suggestions", "placement_of_doc",
           "suggest_for_arm", "suggest_for_person", "summary", "write_next_yaml"]
