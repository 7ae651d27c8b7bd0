"""A warm start of the calibration for a session that grows by a view or a few (the node's guide
recalibrates after every capture): the refinement starts at the previous calibration's solution
(camera, view poses, edge offsets), each new view posed with that camera, so that the closed form
is skipped and Levenberg-Marquardt needs few steps (:data:`~.lm.WARM_START`). The rounds of outlier
rejection run as in the cold path and every solve converges to the same fixed point, so the
result is the cold one to the tolerance of the solves.

It applies only where the cold calibration goes the plain way: the previous views are the first
views of the session now (the same detections), every usable view was posed by the closed form
and refined together, and no view was dropped or added after, no target shape estimated; the
options and the target are the same. Anything else, a new view the camera cannot pose, and a warm
result that would not be plain (a view to drop), is calibrated cold. A warm result's
``K_initial``, ``degeneracy_ratio`` and the closed form's warnings are those of the last cold
calibration of the session (the closed form is not run again)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...detect import Detection
from ...geometry import CircularPointError
from ...targets import Target
from ..solver.lm import WARM_START, levenberg_marquardt
from ..solver.observations import ViewData
from ..solver.problem import Problem
from ..solver.refine import RefineResult
from .initial import pose_to_params, pose_with_camera
from .options import LOSS_SCALES, CalibrationOptions, observations
from .pipeline import Prepared, Refined, cold_calibration, finish, pose_dof, prepare, refine_prepared
from .result import CalibrationError, CalibrationResult


@dataclass(frozen=True)
class IntrinsicStart:
    """What the next call starts from: the views and the options of a plain calibration, its first
    refinement (all of it: the final refinement is the first) and the result."""

    dets: tuple[Detection, ...]
    target: Target
    options: CalibrationOptions
    first: Refined
    calibration: CalibrationResult

    def applies(self, dets: list[Detection], target: Target, options: CalibrationOptions) -> bool:
        """The same target and options, and this start's views the first of ``dets`` (the same
        detections; a view that was not usable may be any unusable one)."""
        return (target is self.target and options == self.options and len(dets) >= len(self.dets)
                and all(a is b or (not a.ok and not b.ok) for a, b in zip(self.dets, dets, strict=False)))


def calibrate_warm(dets: list[Detection], target: Target, options: CalibrationOptions,
                      start: IntrinsicStart | None = None) -> tuple[CalibrationResult, IntrinsicStart | None]:
    """:func:`~.pipeline.calibrate`, warm from ``start`` where it applies (module docstring); and
    the start of the next call (None when this calibration was not plain)."""
    if start is not None and start.applies(dets, target, options):
        prep = prepare(dets, target, options)
        first = _warm_first(dets, target, prep, start)
        if first is not None:
            try:
                cal = finish(dets, target, prep, first)
            except CalibrationError:  # the cold path may restart where the warm one cannot
                cal = None
            if cal is not None and _plain(cal, prep, first):
                return cal, IntrinsicStart(tuple(dets), target, options, first, cal)
    cal, prep, cold = cold_calibration(dets, target, options)
    if cold is None:
        return cal, None
    return cal, IntrinsicStart(tuple(dets), target, options, cold, cal) if _plain(cal, prep, cold) else None


def _plain(cal: CalibrationResult, prep: Prepared, first: Refined) -> bool:
    """Every usable view in the first refinement, and nothing refitted after it."""
    opt = prep.opt
    return (cal.refinement is first.res and list(first.idx) == list(prep.usable) and not opt.target_shape
            and opt.method != "zhang")


def _warm_first(dets: list[Detection], target: Target, prep: Prepared, start: IntrinsicStart) -> Refined | None:
    """The first refinement from the start's first round (its solution before any observation was
    rejected), each new usable view posed with the start's camera; None if one cannot be posed."""
    prev = start.first
    res = prev.res
    if res.first_x is None or res.problem is None or len(res.first_views) != len(prev.idx):
        return None
    new = [k for k in prep.usable if k >= len(start.dets)]
    cam = start.calibration.camera()
    origin, dof = target.local_origin, pose_dof(target)
    views, blocks = list(res.first_views), []
    for k in new:
        view = observations(dets[k], target, origin, prep.opt)
        try:
            block = _polished(view, pose_to_params(pose_with_camera(dets[k], target, cam, origin), dof), res, prep.opt)
        except (CircularPointError, np.linalg.LinAlgError, ValueError):
            return None
        views.append(view)
        blocks.append(block)
    x0 = np.concatenate([res.first_x, *blocks])
    refined = refine_prepared(views, res.K, res.D, [], dof, prep.opt, x0=x0, lm=WARM_START)
    return Refined(refined, [*prev.idx, *new], prev.K_initial, prev.degeneracy_ratio, list(prev.start_warnings))


def _polished(view: ViewData, pose: np.ndarray, res: RefineResult, opt: CalibrationOptions) -> np.ndarray:
    """A new view's parameters (pose, and edge offset when estimated) fitted to its own observations
    with the start's camera held: the closed-form pose is good to a few degrees only."""
    assert res.intr0 is not None and res.problem is not None
    intr = res.problem.unpack(np.asarray(res.x), res.intr0)[0]
    prob = Problem([view], res.problem.dof, (), res.problem.use_offsets, LOSS_SCALES[opt.loss], lens=res.problem.lens)
    x0 = np.r_[pose, 0.0] if prob.use_offsets else pose
    return levenberg_marquardt(prob, x0, intr, LOSS_SCALES[opt.loss], max_iter=30).x
