"""The named modes (modes.py): members are their text, unknown text refused with the choices, and
every place that takes a hand-eye mode turns text into the enum or refuses it there."""

from __future__ import annotations

import pytest

from pascal_calib_ros.calibrate.handeye.options import HandEyeError, HandEyeOptions
from pascal_calib_ros.modes import HandEyeMode, ModeError, parse_mode
from pascal_calib_ros.workflows.suggest import SuggestOptions


def test_a_member_is_its_text_and_unknown_text_is_refused_with_the_choices() -> None:
    assert parse_mode(HandEyeMode, "eye_to_hand", "mode") is HandEyeMode.EYE_TO_HAND
    assert HandEyeMode.EYE_IN_HAND == "eye_in_hand" and f"{HandEyeMode.EYE_IN_HAND}" == "eye_in_hand"
    with pytest.raises(ModeError, match="hand_eye 'eye_on_hand': choose one of eye_in_hand, eye_to_hand"):
        parse_mode(HandEyeMode, "eye_on_hand", "hand_eye")


def test_options_take_text_and_hold_the_enum() -> None:
    assert HandEyeOptions("eye_to_hand").mode is HandEyeMode.EYE_TO_HAND  # type: ignore[arg-type]
    with pytest.raises(HandEyeError, match="unknown hand-eye mode 'sideways'"):
        HandEyeOptions("sideways")  # type: ignore[arg-type]
    assert SuggestOptions(mode="eye_in_hand").mode is HandEyeMode.EYE_IN_HAND  # type: ignore[arg-type]
    assert SuggestOptions(mode="").mode is None  # type: ignore[arg-type]
    with pytest.raises(ModeError, match="--mode 'x'"):
        SuggestOptions(mode="x")  # type: ignore[arg-type]


def test_a_mode_is_written_as_its_text() -> None:
    import json

    import yaml

    doc = {"mode": HandEyeMode.EYE_TO_HAND}
    assert yaml.safe_dump(doc) == "mode: eye_to_hand\n" and json.dumps(doc) == '{"mode": "eye_to_hand"}'
    assert yaml.safe_load(yaml.safe_dump(doc))["mode"] == "eye_to_hand"
