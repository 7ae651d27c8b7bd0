"""NEXT.yaml (io/next_yaml.py): the typed suggestions written and read back to the printed digit,
a file that is not one refused with the reason."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pascal_calib_ros.geometry.placement import Placement
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.next_yaml import (
    ArmProgress,
    NextYamlError,
    Suggestion,
    Suggestions,
    ToolSuggestion,
    next_document,
    read_next_yaml,
    write_next_yaml,
)
from pascal_calib_ros.modes import HandEyeMode


def _arm_suggestions() -> Suggestions:
    view = Transform.from_rotvec([0.3, -0.2, 0.1], [0.01, -0.02, 0.45])
    tool = ToolSuggestion(Transform.from_rotvec([3.0, 0.1, 0.2], [0.5, 0.1, 0.3]), 0.012345678, 0.1234567)
    first = Suggestion(view, Placement((321.04, 240.96), 0.45004, 35.04, 120.0, 12.5), 0.21234567, tool)
    arm = ArmProgress(HandEyeMode.EYE_TO_HAND, "base_link", "tool0", sigma_deg=0.0234567, sigma_mm=0.2345678,
                      goal_deg=0.01, goal_mm=0.1, reach_m=0.3, max_turn_deg=120.0)
    return Suggestions(False, 0.5234567, 0.1, 0.4512345, 7, (first,), arm,
                       (Placement((100.0, 80.0), 0.3, 45.0, 270.0, 0.0),))


def test_written_and_read_back_to_the_printed_digit(tmp_path: Path) -> None:
    s = _arm_suggestions()
    path = write_next_yaml(tmp_path / "sub" / "NEXT.yaml", s)
    back = read_next_yaml(path)
    assert next_document(back) == next_document(s) == yaml.safe_load(path.read_text())
    assert back.arm is not None and back.arm.mode is HandEyeMode.EYE_TO_HAND
    assert back.first is not None and back.first.tool is not None
    assert back.first.tool.predicted_sigma_deg == pytest.approx(0.012346, abs=1e-12)  # rounded to 6 digits
    assert back.first.placement.pixel == (321.0, 241.0) and back.avoided == s.avoided
    doc = yaml.safe_load(path.read_text())
    assert list(doc)[:6] == ["done", "projection_sigma_px", "goal_sigma_px", "distance_m", "views_used", "mode"]
    assert doc["mode"] == "eye_to_hand" and doc["suggestions"][0]["tool"]["translation"] == [0.5, 0.1, 0.3]
    # a person's suggestions: no arm fields, no avoided list, no tool
    person = Suggestions(True, 0.05, 0.1, 0.4, 9, ())
    doc = next_document(read_next_yaml(write_next_yaml(tmp_path / "p.yaml", person)))
    assert doc == {"done": True, "projection_sigma_px": 0.05, "goal_sigma_px": 0.1, "distance_m": 0.4,
                   "views_used": 9, "suggestions": []}


@pytest.mark.parametrize("text, why", [("- a list\n", "not a NEXT.yaml"), ("done: false\n", "KeyError"),
                                       ("{done: false, projection_sigma_px: 1, goal_sigma_px: 1, distance_m: 1, "
                                        "views_used: 3, mode: sideways, frame_id: a, child_frame_id: b}\n",
                                        "choose one of eye_in_hand, eye_to_hand")])
def test_a_file_that_is_not_one_is_refused_with_the_reason(tmp_path: Path, text: str, why: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    with pytest.raises(NextYamlError, match=why):
        read_next_yaml(bad)
    with pytest.raises(NextYamlError, match="cannot read"):
        read_next_yaml(tmp_path / "missing.yaml")
