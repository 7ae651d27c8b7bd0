"""A warm start of the hand-eye estimate for a session that grows by a view or a few (the node's
``~/suggest`` after every capture): the intrinsic calibration warm (:mod:`..warm`), the views'
observations reused, and the first pass of the chain refinement's variance components started at
the previous call's first pass, the new views at their refined camera pose (the later passes start,
as cold, at the pass before). The passes and their sigmas are the cold ones (the arm's sigmas start
at the options' values, as cold): starting each pass at converged sigmas instead would move X by
about as much as the passes' 5 % stopping rule leaves open (a few micrometres), not to the cold
answer. Each pass converges to the same point as cold in fewer steps (:data:`~..lm.WARM_START`).
The chain part starts cold (from the closed form)
when the views kept are not the previous ones followed by new ones, or a previous view alone is
labelled otherwise (its pose turned by a symmetry of the target); a session relabelled as a whole
turns the previous solution with it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...detect import Detection
from ...geometry import Transform
from ..intrinsic.warm import IntrinsicStart
from .options import HandEyeOptions

RELABELLED_DEG = 1.0  # a previous view's pose turned by more than this: labelled otherwise now


@dataclass(frozen=True)
class HandEyeStart:
    """What the next call starts from: the session's views and robot poses as given, the options,
    the intrinsic calibration's start (None: the next one is cold), the chain refinement's views
    (their index in the session and their camera poses as labelled) and the solution of its first
    variance-components pass."""

    dets: tuple[Detection, ...]
    robot: tuple[Transform | None, ...]
    he: HandEyeOptions
    intrinsic: IntrinsicStart | None
    kept: tuple[int, ...]
    poses: tuple[Transform, ...]
    first_pass: np.ndarray

    def applies(self, dets: Sequence[Detection], robot: Sequence[Transform | None], he: HandEyeOptions) -> bool:
        """The same options (mode included), and this start's views and robot poses the first of the
        session now (the same objects)."""
        n = len(self.dets)
        return (he == self.he and len(dets) >= n and len(robot) == len(dets)
                and all(a is b for a, b in zip(self.dets, dets[:n], strict=True))
                and all(a is b for a, b in zip(self.robot, robot[:n], strict=True)))

    def chain_start(self, kept: list[int], poses: list[Transform], offsets: list[float], per_view: int
                    ) -> np.ndarray | None:
        """The first pass's start for the chain refinement of the views ``kept`` (session indices) with
        the camera poses ``poses`` and edge offsets ``offsets`` (the intrinsic refinement's): the
        previous first pass's solution, each new view appended at its pose and offset (``per_view``
        parameters a view, the offset last if estimated); None when the previous views are not the
        first of ``kept``. A session labelled turned as a whole by a symmetry T of the target (the
        labelling most views were detected in changed) turns the previous poses and Y with it: C T,
        Y T; a previous view labelled otherwise alone makes it None."""
        n = len(self.kept)
        if not len(self.first_pass) or tuple(kept[:n]) != self.kept:
            return None
        turns = [a.inverse() @ b for a, b in zip(self.poses, poses[:n], strict=True)]
        T = turns[0]
        if any((t.rotation * T.rotation.inv()).magnitude() > np.radians(RELABELLED_DEG) for t in turns):
            return None
        x = _turned(self.first_pass, T, n, per_view) if T.angle_deg() > RELABELLED_DEG else self.first_pass
        blocks = [np.r_[p.rotvec, p.translation, [o] * (per_view - 6)] for p, o in zip(poses[n:], offsets[n:],
                                                                                        strict=True)]
        return np.concatenate([x, *blocks])


def _turned(x: np.ndarray, T: Transform, n: int, per_view: int) -> np.ndarray:
    """A chain solution (:meth:`~.chain.ChainProblem.pack_chain`'s layout, ``n`` views) in the
    labelling turned by T: every view's pose C T, the target's pose Y T (X stays)."""
    x = x.copy()
    base = len(x) - 12 - per_view * n
    Y = Transform.from_rotvec(x[base + 6:base + 9], x[base + 9:base + 12]) @ T
    x[base + 6:base + 12] = np.r_[Y.rotvec, Y.translation]
    for i in range(n):
        s = base + 12 + per_view * i
        C = Transform.from_rotvec(x[s:s + 3], x[s + 3:s + 6]) @ T
        x[s:s + 6] = np.r_[C.rotvec, C.translation]
    return x
