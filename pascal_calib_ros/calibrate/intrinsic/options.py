"""The options of a calibration and their checks against the target and the views."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ...detect import Detection
from ...targets import Target
from ..solver.observations import ViewData, view_data
from ..solver.problem import DISTORTION_MODELS, SHAPE_NAMES
from ..solver.refine import OUTLIER_K
from .initial import (
    CIRCLE_METHODS,
)
from .result import CalibrationError, ViewReport

METHODS = (*CIRCLE_METHODS, "grid", "zhang")


MIN_VIEWS = 3


@dataclass(frozen=True)
class CalibrationOptions:
    method: str = ""  # empty: the target's natural method (Target.default_method)
    refine: bool = True
    distortion: str = "plumb_bob"
    zero_skew: bool = True
    edge_offsets: bool = True
    use_corners: bool = True  # adjust checkerboard corners too, when the target has them
    max_points_per_edge: int = 720
    max_points_per_view: int = 700  # grids: spread over all edges (speed of the refinement)
    outlier_factor: float = 4.0  # drop a view whose RMS exceeds this times the median
    min_views: int = MIN_VIEWS
    loss: str = "soft_l1"  # the refinement's loss: soft_l1 (robust, scale 0.3 px) or linear (least squares)
    # reject observations beyond this many robust standard deviations of their view (refine.OUTLIER_K); 0: keep all
    outlier_k: float = OUTLIER_K
    # estimate the printed sheet's shape (refine.SHAPE_NAMES: y/x pitch ratio, parabolic warp);
    # targets with circles spread over the sheet (grids) or a checkerboard only
    target_shape: tuple[str, ...] = ()


LOSS_SCALES = {"soft_l1": 0.3, "linear": float("inf")}  # px; inf: least squares


def checked_options(options: CalibrationOptions, target: Target) -> CalibrationOptions:
    """The options with the target's default method filled in; a CalibrationError for any that
    cannot work with this target."""
    opt = replace(options, method=options.method or target.default_method())
    if opt.method not in METHODS:
        raise CalibrationError(f"unknown method {opt.method!r}; choose one of {', '.join(METHODS)}")
    if opt.method not in target.methods():
        raise CalibrationError(f"method {opt.method!r} needs features target {target.name!r} lacks "
                               f"(it supports: {', '.join(target.methods())})")
    if opt.distortion not in DISTORTION_MODELS:
        raise CalibrationError(f"unknown distortion model {opt.distortion!r}; choose one of "
                               f"{', '.join(DISTORTION_MODELS)}")
    unknown = [n for n in opt.target_shape if n not in SHAPE_NAMES]
    if unknown:
        raise CalibrationError(f"unknown target shape parameter(s) {unknown}; choose from {', '.join(SHAPE_NAMES)}")
    if opt.target_shape and not (target.grids or target.boards):
        raise CalibrationError(f"the shape of target {target.name!r} cannot be estimated: it needs features spread "
                               "over the sheet (a ring or disc grid, or a checkerboard)")
    if opt.target_shape and not opt.refine:
        raise CalibrationError("the target shape is estimated by the refinement; drop --target-shape or --no-refine")
    if opt.loss not in LOSS_SCALES:
        raise CalibrationError(f"unknown loss {opt.loss!r}; choose one of {', '.join(LOSS_SCALES)}")
    if not opt.outlier_k >= 0:
        raise CalibrationError(f"the outlier threshold must be 0 (off) or positive, not {opt.outlier_k}")
    return opt


def checked_views(dets: list[Detection], opt: CalibrationOptions) -> tuple[list[ViewReport], list[int]]:
    """A report per view and the indices of the usable ones; a CalibrationError if too few."""
    if not dets:
        raise CalibrationError("no views given")
    sizes = {(d.width, d.height) for d in dets}
    if len(sizes) > 1:
        raise CalibrationError(f"views have different image sizes {sorted(sizes)}: one camera mode per session")
    reports = [ViewReport(d.name or f"view{k}", d.ok, d.reason) for k, d in enumerate(dets)]
    usable = [k for k, d in enumerate(dets) if d.ok]
    if len(usable) < opt.min_views:
        raise CalibrationError(
            f"{len(usable)} usable view(s) of {len(dets)}; need at least {opt.min_views}. "
            + _rejection_summary(reports))
    # a model with more coefficients than plumb_bob's five needs one more view per coefficient
    n_coef = len(DISTORTION_MODELS[opt.distortion])
    need = opt.min_views + max(0, n_coef - 5)
    if len(usable) < need:
        raise CalibrationError(f"{len(usable)} usable view(s) for the {opt.distortion} model's {n_coef} distortion "
                               f"coefficients; take at least {need} views spread over the image (corners too), or "
                               "choose a model with fewer coefficients (plumb_bob)")
    return reports, usable


def _rejection_summary(reports: list[ViewReport]) -> str:
    reasons: dict[str, int] = {}
    for r in reports:
        if r.reason:
            reasons[r.reason] = reasons.get(r.reason, 0) + 1
    if not reasons:
        return ""
    return "Rejected: " + "; ".join(f"{n} x {why}" for why, n in sorted(reasons.items(), key=lambda x: -x[1]))


def observations(det: Detection, target: Target, origin: tuple[float, float], opt: CalibrationOptions) -> ViewData:
    """:func:`~..solver.observations.view_data` with the options' budget of points per edge and
    per view."""
    n_edges = max(len(det.edges), 1)
    per_edge = max(8, min(opt.max_points_per_edge, opt.max_points_per_view // n_edges))
    return view_data(det, target, origin, per_edge, opt.use_corners)
