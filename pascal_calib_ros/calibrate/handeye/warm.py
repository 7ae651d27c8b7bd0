"""A warm start of the hand-eye estimate for a session that grows by a view or a few (the node's
``~/suggest`` after every capture): the intrinsic calibration warm (:mod:`..warm`), the views'
observations reused, and each pass of the chain refinement's variance components started at the
previous call's same pass, the new views at their refined camera pose. The passes and their
sigmas are the cold ones (the arm's sigmas start at the options' values, as cold), each pass
converging to the same point in a few steps. The chain part starts cold (from the closed form)
when the views kept are not the previous ones followed by new ones, or a previous view is labelled
otherwise (its pose turned by a symmetry of the target)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...detect.detection import Detection
from ...geometry.transform import Transform
from ..warm import IntrinsicStart
from .options import HandEyeOptions

RELABELLED_DEG = 1.0  # a previous view's pose turned by more than this: labelled otherwise now


@dataclass(frozen=True)
class HandEyeStart:
    """What the next call starts from: the session's views and robot poses as given, the options,
    the intrinsic calibration's start (None: the next one is cold), the chain refinement's views
    (their index in the session and their camera poses as labelled) and the solution of each of its
    variance-components passes."""

    dets: tuple[Detection, ...]
    robot: tuple[Transform | None, ...]
    he: HandEyeOptions
    intrinsic: IntrinsicStart | None
    kept: tuple[int, ...]
    poses: tuple[Transform, ...]
    passes: tuple[np.ndarray, ...]

    def applies(self, dets: Sequence[Detection], robot: Sequence[Transform | None], he: HandEyeOptions) -> bool:
        """The same options (mode included), and this start's views and robot poses the first of the
        session now (the same objects)."""
        n = len(self.dets)
        return (he == self.he and len(dets) >= n and len(robot) == len(dets)
                and all(a is b for a, b in zip(self.dets, dets[:n], strict=True))
                and all(a is b for a, b in zip(self.robot, robot[:n], strict=True)))

    def chain_passes(self, kept: list[int], poses: list[Transform], offsets: list[float], per_view: int
                     ) -> list[np.ndarray] | None:
        """Each pass's start for the chain refinement of the views ``kept`` (session indices) with the
        camera poses ``poses`` and edge offsets ``offsets`` (the intrinsic refinement's): the previous
        pass's solution, each new view appended at its pose and offset (``per_view`` parameters a
        view, the offset last if estimated); None when the previous views are not the first of
        ``kept`` or one is labelled otherwise."""
        n = len(self.kept)
        if not self.passes or tuple(kept[:n]) != self.kept:
            return None
        for a, b in zip(self.poses, poses[:n], strict=True):
            if (a.rotation * b.rotation.inv()).magnitude() > np.radians(RELABELLED_DEG):
                return None
        blocks = [np.r_[p.rotvec, p.translation, [o] * (per_view - 6)] for p, o in zip(poses[n:], offsets[n:],
                                                                                        strict=True)]
        return [np.concatenate([x, *blocks]) for x in self.passes]
