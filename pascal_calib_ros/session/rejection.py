"""Why a frame or a view was not stored, as a kind and the words a person reads.

The kind is what code decides on (a capture waits on through motion but not a missing robot pose;
the guide avoids a suggestion only when the view itself was refused); the message is what the
status, the capture's answer and the live picture show, unchanged. Counting groups messages by
their text before the first parenthesis (the per-frame figures left out)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class RejectionKind(Enum):
    """What a refusal concerns."""

    TARGET = "target"  # the detector refused the view: the feature's own reason
    MOVING = "moving"  # the target or the robot moved between frames (or nothing to compare with yet)
    NO_POSE = "no robot pose"  # no robot pose at the frame's stamp
    BAD_FRAME = "bad frame"  # the message could not be converted to an image
    IMAGE_SIZE = "image size"  # a frame of another size than the session's
    NO_PLACE = "no place"  # the view's placement could not be measured
    TOO_SIMILAR = "too similar"  # the view adds nothing to the stored ones
    STORE_FULL = "store full"  # the session holds as many views as it may

    @property
    def is_the_view(self) -> bool:
        """Whether the refusal concerns the view itself (what a guide must not suggest again), not
        its timing (motion, the robot pose)."""
        return self not in (RejectionKind.MOVING, RejectionKind.NO_POSE)


@dataclass(frozen=True)
class Rejection:
    """A refusal: its kind and its message (module docstring)."""

    kind: RejectionKind
    message: str

    def __str__(self) -> str:
        return self.message

    @property
    def key(self) -> str:
        """The message without the per-frame figures: what refusals are counted by."""
        return rejection_key(self.message)


def rejection_key(message: str) -> str:
    """``message`` before its first parenthesis, stripped."""
    return message.split("(")[0].strip()


__all__ = ["Rejection", "RejectionKind", "rejection_key"]
