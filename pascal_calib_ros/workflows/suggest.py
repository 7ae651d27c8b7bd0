"""``pascal-calib suggest``: from the views captured so far, the next views to take (NEXT.yaml),
for a person holding the target or a script driving a robot arm, until the accuracy asked for is
reached. ROS-free; the node's ``~/suggest`` will call the same functions.

The document and its file: :mod:`..io.next_yaml` (:class:`~..io.next_yaml.Suggestions`).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..analysis import (
    DISTINCT_ROLL_DEG,
    ArmGoals,
    Linearisation,
    RankedView,
    TrustRegion,
    ViewPredictor,
    arm_model,
    distinct_from_all,
    suggest_arm_views,
    suggest_views,
)
from ..calibrate import DISTORTION_MODELS, MIN_VIEWS, CalibrationError, CalibrationOptions, calibrate
from ..calibrate.handeye import HandEyeOptions, HandEyeStart, calibrate_hand_eye_warm
from ..detect import Detection
from ..errors import PascalCalibError
from ..geometry import ImageSize, Placement, Transform
from ..io import ArmProgress, Suggestion, Suggestions, ToolSuggestion
from ..modes import HandEyeMode, parse_mode
from ..targets import Target


class SuggestError(PascalCalibError):
    """The inputs give no suggestion; the message says why and what to do."""


@dataclass(frozen=True)
class SuggestOptions:
    n: int = 5
    goal_sigma_px: float = 0.1
    distortion: str = "plumb_bob"
    mode: HandEyeMode | None = None  # with robot poses
    reach: float = 0.3  # m
    max_turn: float = 120.0  # deg
    goal_deg: float = 0.01  # hand-eye rotation sigma goal (arms)
    goal_mm: float = 0.1  # hand-eye translation sigma goal (arms)

    def __post_init__(self) -> None:
        if self.mode is not None:  # text given for the mode becomes the enum ("" or None: no arm)
            object.__setattr__(self, "mode", parse_mode(HandEyeMode, self.mode, "--mode") if self.mode else None)

    def problem(self) -> str:
        """Why these options cannot be used ("" if they can)."""
        if self.n < 1:
            return f"-n {self.n}: ask for at least one suggestion"
        for name, v in (("--goal-sigma", self.goal_sigma_px), ("--reach", self.reach), ("--max-turn", self.max_turn),
                        ("--goal-deg", self.goal_deg), ("--goal-mm", self.goal_mm)):
            if not (np.isfinite(v) and v > 0):
                return f"{name} {v}: give a finite value > 0"
        if self.distortion not in DISTORTION_MODELS:
            return f"--distortion {self.distortion}: choose one of {', '.join(DISTORTION_MODELS)}"
        return ""


def _suggestion(r: RankedView, tool: ToolSuggestion | None = None) -> Suggestion:
    return Suggestion(r.pose, r.placement, r.predicted_sigma_px, tool)


def _usable(dets: list[Detection]) -> int:
    n = sum(d.ok for d in dets)
    if n < MIN_VIEWS:
        raise SuggestError(f"{n} usable view(s); suggestions need at least {MIN_VIEWS} (take views of the whole "
                           "target tilted about 30-40 degrees about different axes, then ask again)")
    return n


def suggest_for_person(dets: list[Detection], target: Target, opt: SuggestOptions,
                       avoid: list[Placement] | None = None) -> Suggestions:
    """The next views for views without robot poses; none of its suggestions in the
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
        s = suggest_views(res.refinement, target, res.size, opt.n, avoid=avoid)
    return Suggestions(bool(s.sigma_px <= opt.goal_sigma_px), s.sigma_px, opt.goal_sigma_px, s.distance, res.n_used,
                       tuple(_suggestion(r) for r in s.suggestions), avoided=tuple(avoid))


def suggest_for_arm(dets: list[Detection], robot: list[Transform | None], target: Target, opt: SuggestOptions,
                    frames: tuple[str, str], avoid: list[Placement] | None = None) -> Suggestions:
    """The next tool poses for an arm session (``robot[i]``: T_base_tool of view i, or None)."""
    return arm_suggestions(dets, robot, target, opt, frames, avoid=avoid)[0]


def arm_suggestions(dets: list[Detection], robot: list[Transform | None], target: Target, opt: SuggestOptions,
                    frames: tuple[str, str], start: HandEyeStart | None = None,
                    avoid: list[Placement] | None = None) -> tuple[Suggestions, HandEyeStart]:
    """:func:`suggest_for_arm`'s answer, its hand-eye estimate warm from a previous call's ``start``
    where it applies (:mod:`..calibrate.handeye.warm`: the same estimate to the solves' tolerance;
    "done" from the projection sigma of these views), and the start of the next call. ``avoid``:
    placements whose views were refused; the ranking is asked for more views and those in their
    neighbourhood (not distinct, the arm's roll counted) are left out."""
    avoid = list(avoid or [])
    if opt.mode is None:
        raise SuggestError("arm suggestions need the hand-eye mode (eye_in_hand or eye_to_hand)")
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
        intrinsic = ViewPredictor(Linearisation.of_refinement(ref), ImageSize(w, hgt))
        model = arm_model(h, poses, target, intrinsic.noise, ImageSize(w, hgt))  # type: ignore[arg-type]
        trust = TrustRegion(tuple(poses), opt.reach, opt.max_turn)  # type: ignore[arg-type]
        s = suggest_arm_views(model, target, trust, opt.n + 3 * len(avoid),
                              ArmGoals(opt.goal_sigma_px, opt.goal_deg, opt.goal_mm))
        sigma = intrinsic.sigma_now()
    kept = s.suggestions
    if avoid and kept:
        new = distinct_from_all([a.view.placement for a in kept], avoid, ImageSize(w, hgt), DISTINCT_ROLL_DEG)
        kept = [a for a, k in zip(kept, new, strict=True) if k]
    kept = kept[:opt.n]
    done = sigma <= opt.goal_sigma_px and s.rotation_deg <= opt.goal_deg and s.translation_mm <= opt.goal_mm
    arm = ArmProgress(opt.mode, frames[0], frames[1], sigma_deg=s.rotation_deg, sigma_mm=s.translation_mm,
                      goal_deg=opt.goal_deg, goal_mm=opt.goal_mm, reach_m=opt.reach, max_turn_deg=opt.max_turn)
    sugg = tuple(_suggestion(a.view, ToolSuggestion(a.tool, a.predicted_rotation_deg, a.predicted_translation_mm))
                 for a in kept)
    return Suggestions(bool(done), sigma, opt.goal_sigma_px, intrinsic.distance_now, len(used), sugg, arm,
                       tuple(avoid)), nxt


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
                frames: tuple[str, str], avoid: list[Placement] | None = None) -> Suggestions:
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


def summary(s: Suggestions) -> str:
    """Lines for people."""
    lines = [f"projection sigma {s.projection_sigma_px:.3f} px (worst over the whole image, at "
             f"{s.distance_m:.2f} m; goal {s.goal_sigma_px:g} px) from {s.views_used} views"]
    if s.arm is not None:
        lines.append(f"hand-eye sigma {s.arm.sigma_deg:.4f} deg, {s.arm.sigma_mm:.3f} mm "
                     f"(goals {s.arm.goal_deg:g} deg, {s.arm.goal_mm:g} mm)")
    lines.append("DONE: the views reach the goal" if s.done else "not done yet; next views, best first:")
    for k, x in enumerate(s.suggestions, 1):
        p = x.placement
        line = (f"  {k}. target centre at pixel ({p.pixel[0]:.0f}, {p.pixel[1]:.0f}), {p.distance:.2f} m, "
                f"tilted {p.tilt_deg:.0f} deg about {p.axis_deg:.0f} deg, rolled {p.roll_deg:.0f}: "
                f"predicted sigma {x.predicted_sigma_px:.3f} px")
        if x.tool is not None:
            line += f", hand-eye {x.tool.predicted_sigma_deg:.4f} deg {x.tool.predicted_sigma_mm:.3f} mm"
        lines.append(line)
    for p in s.avoided:
        lines.append(f"  avoided (a view there was refused): centre at pixel ({p.pixel[0]:.0f}, "
                     f"{p.pixel[1]:.0f}), {p.distance:.2f} m, tilted {p.tilt_deg:.0f} deg about "
                     f"{p.axis_deg:.0f} deg, and its neighbourhood")
    return "\n".join(lines)


__all__ = ["SuggestError", "SuggestOptions", "WarmArmSuggestions", "arm_suggestions", "suggest_for_arm",
           "suggest_for_person", "summary"]
