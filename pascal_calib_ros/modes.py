"""The named modes users choose, as enums whose values are the strings they type (ROS parameters,
CLI options, files): a member is a ``str`` (``StrEnum``), so it compares equal to its text and is
written as it (JSON, and YAML through the representer registered below); :func:`parse_mode` turns
text into a member or says what the choices are."""

from __future__ import annotations

from enum import StrEnum
from typing import TypeVar

import yaml

from .errors import PascalCalibError


class HandEyeMode(StrEnum):
    """Where the camera is in a robot-arm session (easy_handeye2's names)."""

    EYE_IN_HAND = "eye_in_hand"  # on the tool: X = tool_T_camera
    EYE_TO_HAND = "eye_to_hand"  # fixed beside the arm: X = base_T_camera


def _represent_mode(dumper: yaml.SafeDumper, mode: StrEnum) -> yaml.Node:
    return dumper.represent_str(mode.value)


# every file writer (safe_dump) writes a mode as its text: a member exists only where this module was imported
yaml.SafeDumper.add_multi_representer(StrEnum, _represent_mode)


class ModeError(PascalCalibError):
    """A mode's text is none of its choices."""


M = TypeVar("M", bound=StrEnum)


def parse_mode(kind: type[M], text: str, what: str) -> M:
    """The member of ``kind`` whose value is ``text``; a :class:`ModeError` naming ``what`` and the choices."""
    try:
        return kind(text)
    except ValueError:
        raise ModeError(f"{what} {text!r}: choose one of {', '.join(m.value for m in kind)}") from None


__all__ = ["HandEyeMode", "ModeError", "parse_mode"]
