"""Views whose robot pose contradicts their images (a wrong frame, a pose from another view, an arm
that moved during the exposure): each view is tested against X and Y solved from the other views
(leave one out); the worst is dropped while it exceeds max(the floor, 8 x the others' median
disagreement). A view is blamed only if it also disagrees beyond the floor with the solution from
all views: a subset with too little spread (a single ring's views, two of them around the same
centre) can solve to a wrong X, or extrapolate badly, and would then blame a good view. (Asking
also that the others fit among themselves kept every view when two were wrong: each one's others
hold the other.)"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...geometry import Transform
from .closed_form import chain_disagreement, complete_ring_poses
from .options import MIN_VIEWS, HandEyeError, HandEyeOptions

Solver = Callable[[list[int]], tuple[Transform, Transform, list[Transform]]]  # views -> X, Y, their poses


@dataclass(frozen=True)
class Disagreement:
    """A dropped view's disagreement with the chain of the others (mm, deg) and why it was dropped."""

    mm: float
    deg: float
    reason: str


def _fits_all(M: list[Transform], C: list[Transform], solve: Solver, he: HandEyeOptions, active: list[int]
              ) -> list[bool]:
    """Per active view whether it agrees within the floor (``outlier_mm``, ``outlier_deg``) with the
    chain of X and Y solved from all active views (all False if they do not solve)."""
    try:
        Xa, Ya, Ca = solve(active)
    except HandEyeError:
        return [False] * len(active)
    mm, deg = chain_disagreement([M[i] for i in active], Xa, Ya, Ca, he.mode)
    return [bool(m <= he.outlier_mm and d <= he.outlier_deg) for m, d in zip(mm, deg, strict=True)]


def drop_disagreeing_views(M: list[Transform], C: list[Transform], solve: Solver, he: HandEyeOptions,
                           axisymmetric: bool) -> tuple[list[int], dict[int, Disagreement]]:
    """(the views kept, the dropped ones with their disagreement), indices into M and C (module
    docstring); ``solve`` gives X, Y and the views' poses from a subset."""
    active = list(range(len(M)))
    dropped: dict[int, Disagreement] = {}
    while len(active) > MIN_VIEWS:
        fits_all = _fits_all(M, C, solve, he, active)
        worst: tuple[float, int, float, float, float, float] | None = None
        for j, a in enumerate(active):
            if fits_all[j]:
                continue  # within the floor of the solution from all views: a weak subset of the others blames it
            others = active[:j] + active[j + 1:]
            try:
                Xo, Yo, Co = solve(others)
            except HandEyeError:
                continue
            mo, do = chain_disagreement([M[i] for i in others], Xo, Yo, Co, he.mode)
            lim_mm = max(he.outlier_mm, 8 * float(np.median(mo)))
            lim_deg = max(he.outlier_deg, 8 * float(np.median(do)))
            cw = complete_ring_poses([M[a]], Xo, Yo, [C[a]]) if axisymmetric else [C[a]]
            mw, dw = chain_disagreement([M[a]], Xo, Yo, cw, he.mode)
            score = max(mw[0] / lim_mm, dw[0] / lim_deg)
            if worst is None or score > worst[0]:
                worst = (score, j, float(mw[0]), float(dw[0]), lim_mm, lim_deg)
        if worst is None or worst[0] <= 1.0:
            break
        _, j, mw_, dw_, lim_mm, lim_deg = worst
        dropped[active[j]] = Disagreement(mw_, dw_, f"robot pose disagrees with the image: {mw_:.1f} mm, {dw_:.2f} "
                                                    f"deg against the chain of the other views (limit {lim_mm:.1f} mm, "
                                                    f"{lim_deg:.2f} deg): wrong pose, or the arm moved during the "
                                                    "exposure")
        active = active[:j] + active[j + 1:]
    return active, dropped
