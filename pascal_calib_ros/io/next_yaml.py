"""NEXT.yaml: the guide's suggestions (``pascal-calib suggest``, the node's ``~/suggest``) as one typed
value, :class:`Suggestions`, written and read back here; the ROS layer turns the same value into
messages. Numbers are rounded when written (the value keeps them whole).

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

With robot poses also ``mode``, ``frame_id``, ``child_frame_id``, ``hand_eye_sigma_deg`` and
``hand_eye_sigma_mm`` now (sigma of X from the views' information, norms over the axes), their
goals, the trust region (``reach_m``, ``max_turn_deg``), and ``done`` requires those goals too.
With placements to avoid (suggestions whose views the detector refused) also ``avoided``: their
placements; no suggestion is in their neighbourhood.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..errors import PascalCalibError
from ..geometry import Placement, Transform
from ..modes import HandEyeMode, parse_mode
from .atomic import write_text_atomic


class NextYamlError(PascalCalibError):
    """A NEXT.yaml that cannot be read; the message says which field."""


@dataclass(frozen=True)
class ToolSuggestion:
    """An arm's suggestion: the tool pose T_base_tool and the hand-eye sigma once its view is added."""

    pose: Transform
    predicted_sigma_deg: float
    predicted_sigma_mm: float


@dataclass(frozen=True)
class Suggestion:
    """One view to take: where the target goes (``camera_T_target`` and the same as a placement a
    person reads), the worst projection sigma once it is added, and for an arm the tool pose."""

    camera_T_target: Transform
    placement: Placement
    predicted_sigma_px: float
    tool: ToolSuggestion | None = None


@dataclass(frozen=True)
class ArmProgress:
    """An arm session's hand-eye figures now, its goals and the trust region suggestions stay in."""

    mode: HandEyeMode
    frame_id: str  # POSES.yaml's base frame
    child_frame_id: str  # its tool frame
    sigma_deg: float
    sigma_mm: float
    goal_deg: float
    goal_mm: float
    reach_m: float
    max_turn_deg: float


@dataclass(frozen=True)
class Suggestions:
    """The guide's answer: the figures now, the goal, and the next views best first."""

    done: bool
    projection_sigma_px: float
    goal_sigma_px: float
    distance_m: float
    views_used: int
    suggestions: tuple[Suggestion, ...]
    arm: ArmProgress | None = None
    avoided: tuple[Placement, ...] = ()

    @property
    def first(self) -> Suggestion | None:
        """The best suggestion (None when there is none)."""
        return self.suggestions[0] if self.suggestions else None


def _pose_doc(T: Transform) -> dict[str, list[float]]:
    return {"translation": [round(float(v), 6) for v in T.translation],
            "rotation": [round(float(v), 7) for v in T.quat]}


def _pose_of(doc: Any) -> Transform:
    return Transform.from_quat([float(v) for v in doc["rotation"]], [float(v) for v in doc["translation"]])


def placement_doc(p: Placement) -> dict[str, Any]:
    """NEXT.yaml's ``placement`` mapping."""
    return {"pixel": [round(p.pixel[0], 1), round(p.pixel[1], 1)], "distance_m": round(p.distance, 4),
            "tilt_deg": round(p.tilt_deg, 1), "tilt_axis_deg": round(p.axis_deg, 1), "roll_deg": round(p.roll_deg, 1)}


def placement_of_doc(doc: Any) -> Placement:
    """The :class:`Placement` of NEXT.yaml's ``placement`` mapping."""
    u, v = (float(x) for x in doc["pixel"])
    return Placement((u, v), float(doc["distance_m"]), float(doc["tilt_deg"]), float(doc["tilt_axis_deg"]),
                     float(doc.get("roll_deg", 0.0)))


def _suggestion_doc(s: Suggestion) -> dict[str, Any]:
    d: dict[str, Any] = {"camera_T_target": _pose_doc(s.camera_T_target),
                         "predicted_sigma_px": round(s.predicted_sigma_px, 5), "placement": placement_doc(s.placement)}
    if s.tool is not None:
        d["tool"] = _pose_doc(s.tool.pose)
        d["predicted_hand_eye_sigma_deg"] = round(s.tool.predicted_sigma_deg, 6)
        d["predicted_hand_eye_sigma_mm"] = round(s.tool.predicted_sigma_mm, 5)
    return d


def _suggestion_of(d: Any) -> Suggestion:
    tool = None
    if "tool" in d:
        tool = ToolSuggestion(_pose_of(d["tool"]), float(d["predicted_hand_eye_sigma_deg"]),
                              float(d["predicted_hand_eye_sigma_mm"]))
    return Suggestion(_pose_of(d["camera_T_target"]), placement_of_doc(d["placement"]), float(d["predicted_sigma_px"]),
                      tool)


def next_document(s: Suggestions) -> dict[str, Any]:
    """NEXT.yaml's document (module docstring), numbers rounded."""
    doc: dict[str, Any] = {"done": bool(s.done), "projection_sigma_px": round(s.projection_sigma_px, 5),
                           "goal_sigma_px": s.goal_sigma_px, "distance_m": round(s.distance_m, 4),
                           "views_used": s.views_used}
    if s.arm is not None:
        a = s.arm
        doc.update({"mode": a.mode.value, "frame_id": a.frame_id, "child_frame_id": a.child_frame_id,
                    "hand_eye_sigma_deg": round(a.sigma_deg, 6), "hand_eye_sigma_mm": round(a.sigma_mm, 5),
                    "goal_hand_eye_sigma_deg": a.goal_deg, "goal_hand_eye_sigma_mm": a.goal_mm, "reach_m": a.reach_m,
                    "max_turn_deg": a.max_turn_deg})
    doc["suggestions"] = [_suggestion_doc(x) for x in s.suggestions]
    if s.avoided:
        doc["avoided"] = [placement_doc(p) for p in s.avoided]
    return doc


def suggestions_of_document(doc: Any) -> Suggestions:
    """The :class:`Suggestions` of a NEXT.yaml document (a KeyError, TypeError or ValueError when a
    field is missing or malformed; :func:`read_next_yaml` says which file)."""
    if not isinstance(doc, dict) or not isinstance(doc.get("suggestions", []), list):
        raise ValueError("not a NEXT.yaml document")
    arm = None
    if "mode" in doc:
        arm = ArmProgress(parse_mode(HandEyeMode, str(doc["mode"]), "mode"), str(doc["frame_id"]),
                          str(doc["child_frame_id"]), sigma_deg=float(doc["hand_eye_sigma_deg"]),
                          sigma_mm=float(doc["hand_eye_sigma_mm"]), goal_deg=float(doc["goal_hand_eye_sigma_deg"]),
                          goal_mm=float(doc["goal_hand_eye_sigma_mm"]), reach_m=float(doc["reach_m"]),
                          max_turn_deg=float(doc["max_turn_deg"]))
    return Suggestions(bool(doc["done"]), float(doc["projection_sigma_px"]), float(doc["goal_sigma_px"]),
                       float(doc["distance_m"]), int(doc["views_used"]),
                       tuple(_suggestion_of(d) for d in doc.get("suggestions", [])), arm,
                       tuple(placement_of_doc(p) for p in doc.get("avoided", [])))


def write_next_yaml(path: str | Path, s: Suggestions) -> Path:
    """Write NEXT.yaml whole or not at all (:mod:`.atomic`); its path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(p, yaml.safe_dump(next_document(s), sort_keys=False, default_flow_style=None))
    return p


def read_next_yaml(path: str | Path) -> Suggestions:
    """The :class:`Suggestions` of a NEXT.yaml file; a :class:`NextYamlError` says why it cannot be read."""
    try:
        return suggestions_of_document(yaml.safe_load(Path(path).read_text()))
    except (OSError, ValueError, TypeError, KeyError, yaml.YAMLError) as e:
        raise NextYamlError(f"{path}: cannot read it ({type(e).__name__}: {e}); give a NEXT.yaml that "
                            "pascal-calib suggest wrote") from None


__all__ = ["ArmProgress", "NextYamlError", "Suggestion", "Suggestions", "ToolSuggestion", "next_document",
           "placement_doc", "placement_of_doc", "read_next_yaml", "suggestions_of_document", "write_next_yaml"]
