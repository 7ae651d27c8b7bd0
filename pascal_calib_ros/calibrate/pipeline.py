"""Views -> closed-form initialisation -> joint refinement -> :class:`CalibrationResult`.

A failure is a :class:`CalibrationError` whose message a user can act on; per-view problems are
kept as reasons beside the views rather than raised.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..analysis.residual_stats import ModelBias, ResidualSamples, model_bias, radial, regional, residual_samples
from ..detect.detection import Detection
from ..errors import PascalCalibError
from ..geometry.camera import Camera
from ..geometry.circular import CircularPointError
from ..geometry.iac import DegenerateViewsError, IacSolution
from ..geometry.lens import DISTORTION_CHOICES, LensModel
from ..targets import Target
from .diagnostics import consistent_rays, observed_field_mask
from .initial import (
    CIRCLE_METHODS,
    grid_homography_init,
    intrinsics_closed_form,
    pose_from_circles,
    pose_from_view,
    pose_to_params,
    pose_with_camera,
)
from .plumbline import (
    division_parameter,
    equidistant_focal,
    plumb_bob_from_division,
    undistort_detections,
    virtual_pinhole_detections,
)
from .refine import (
    DISTORTION_MODELS,
    OUTLIER_K,
    SHAPE_NAMES,
    RefineResult,
    ViewData,
    intrinsic_names,
    refine,
    shape_frame_of,
)
from .uncertainty import ProjectionUncertainty
from .zhang import calibrate_zhang

METHODS = (*CIRCLE_METHODS, "grid", "zhang")
MIN_VIEWS = 3


class CalibrationError(PascalCalibError):
    """The session cannot be calibrated; the message says why and what to do."""


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
    # projection uncertainty at this distance (m; inf: at infinity); None: the median distance to the target's centre
    projection_distance: float | None = None
    # estimate the printed sheet's shape (refine.SHAPE_NAMES: y/x pitch ratio, parabolic warp);
    # targets with circles spread over the sheet (grids) or a checkerboard only
    target_shape: tuple[str, ...] = ()


@dataclass
class ViewReport:
    name: str
    used: bool
    reason: str = ""
    rms: float = float("nan")
    edge_offset: float = float("nan")
    # observations left out: corners the detector's check rejected (not on a saddle), and edge points /
    # corners the refinement rejected as outliers
    unmeasured_corners: int = 0
    rejected_edges: int = 0
    rejected_corners: int = 0

    def rejections(self) -> str:
        """'2 corners not on a saddle, 1 corner and 3 edge points rejected as outliers', or ''."""
        parts = []
        if self.unmeasured_corners:
            parts.append(f"{_n(self.unmeasured_corners, 'corner')} rejected by the detector (not on a saddle)")
        out = [_n(n, what) for n, what in ((self.rejected_corners, "corner"), (self.rejected_edges, "edge point")) if n]
        if out:
            parts.append(" and ".join(out) + " rejected as outliers")
        return ", ".join(parts)


def _n(n: int, noun: str) -> str:
    return f"{n} {noun}{'s' if n != 1 else ''}"


@dataclass
class CalibrationResult:
    K: np.ndarray
    D: np.ndarray
    width: int
    height: int
    method: str
    rms: float
    std: dict[str, float]
    degeneracy_ratio: float
    views: list[ViewReport]
    warnings: list[str] = field(default_factory=list)
    K_initial: np.ndarray | None = None
    refined: bool = True
    distortion_model: str = "plumb_bob"  # what was asked for (a DISTORTION_CHOICES key)
    poses: list[np.ndarray] = field(default_factory=list)
    # per used view (same order as the used entries of ``views``): edge points and their signed
    # residuals (px, positive outwards), for reports
    edge_points: list[np.ndarray] = field(default_factory=list)
    edge_residuals: list[np.ndarray] = field(default_factory=list)
    edge_circles: list[np.ndarray] = field(default_factory=list)  # Target.circles index of each point
    circle_names: list[str] = field(default_factory=list)  # feature name of each Target.circles entry
    # estimated target shape (empty unless asked for): value, standard deviation, and how much
    # each intrinsic moved against a fit that assumes the nominal flat sheet (fx, fy, cx, cy, the
    # flat fit's rms_flat and, with the pitch ratio, its pitch_aspect_correlation with fy/fx)
    shape: dict[str, float] = field(default_factory=dict)
    shape_std: dict[str, float] = field(default_factory=dict)
    shape_effect: dict[str, float] = field(default_factory=dict)
    # mrcal's projection uncertainty at the median target distance over a grid of the image (None:
    # no refinement); :meth:`projection_summary` over the observed field
    projection: ProjectionUncertainty | None = None
    refinement: RefineResult | None = None  # the final refinement (solution, covariance), for uncertainty.py
    # per used view: checkerboard corners (M, 2) and their residuals (observed - predicted)
    corner_points: list[np.ndarray] = field(default_factory=list)
    corner_residuals: list[np.ndarray] = field(default_factory=list)
    # what the standard deviations in ``std`` are (report.json's std_model)
    std_model: str = ""

    def feature_points(self) -> list[np.ndarray]:
        """Per used view, its edge points and checkerboard corners (N, 2): what the observed field
        is the union of the convex hulls of."""
        out = []
        for k, p in enumerate(self.edge_points):
            c = self.corner_points[k] if k < len(self.corner_points) else np.zeros((0, 2))
            out.append(np.concatenate([np.asarray(p, float).reshape(-1, 2), np.asarray(c, float).reshape(-1, 2)]))
        return out

    def observed_field(self, margin: float = 0.0) -> np.ndarray:
        """(height, width) bool: the union of the used views' convex hulls of feature points."""
        return observed_field_mask(self.feature_points(), self.width, self.height, margin)

    def model_bias(self) -> ModelBias:
        """The verdict whether the residuals carry a pattern beyond noise (:mod:`.residual_stats`)."""
        s = self.residual_samples()
        return model_bias(regional(s, self.width, self.height), radial(s, (float(self.K[0, 2]), float(self.K[1, 2]))),
                          self.width, self.height, self.model)

    def with_model_bias_warning(self) -> CalibrationResult:
        """Add the model-bias verdict to the warnings when a bias is detected (so the summary, the
        CLI and the node's answer say it); returns self."""
        if self.refined and self.edge_points:
            mb = self.model_bias()
            if mb.detected and mb.hint not in self.warnings:
                self.warnings.append(mb.hint)
        return self

    def residual_samples(self) -> ResidualSamples:
        """Every edge and corner residual as a vector at its pixel (:mod:`.residual_stats`)."""
        kappa = self.refinement.kappa if self.refinement is not None else (1.0, 1.0)
        return residual_samples(self.edge_points, self.edge_residuals, self.edge_circles, self.corner_points,
                                self.corner_residuals, kappa)

    def projection_summary(self) -> dict[str, float] | None:
        """Median and worst projection sigma (px) over the observed field, and the distance (m)."""
        if self.projection is None:
            return None
        return self.projection.summary(self.observed_field() if self.edge_points else None)

    def projection_line(self) -> str:
        """One line for people: 'projection sigma 0.04 px median, 0.2 px worst in the observed field'."""
        s = self.projection_summary()
        if s is None or not np.isfinite(s["median_px"]):
            return "projection sigma: not available"
        where = (f"points at {s['distance_m']:.2f} m" if np.isfinite(s["distance_m"]) else "points at infinity")
        if self.projection is not None and self.projection.default_distance:
            where += ", the median distance to the target's centre"
        return (f"projection sigma {s['median_px']:.3f} px median, {s['worst_px']:.3f} px worst in the observed "
                f"field ({where})")

    @property
    def model(self) -> str:
        """The ROS ``distortion_model`` of D (plumb_bob, rational_polynomial, equidistant)."""
        return DISTORTION_CHOICES[self.distortion_model][0].name

    def camera(self) -> Camera:
        return Camera(self.K, self.D, self.width, self.height, self.model)

    def edge_count(self, view: ViewReport) -> int:
        """The number of edge points a used view contributed (0 for a corner-only view)."""
        used = [v for v in self.views if v.used]
        k = next((i for i, v in enumerate(used) if v is view), None)
        return len(self.edge_points[k]) if k is not None and k < len(self.edge_points) else 0

    @property
    def n_used(self) -> int:
        return sum(v.used for v in self.views)

    def summary_line(self) -> str:
        K = self.K
        return (f"fx={K[0, 0]:.2f} fy={K[1, 1]:.2f} cx={K[0, 2]:.2f} cy={K[1, 2]:.2f} "
                f"rms={self.rms:.3f}px views={self.n_used}/{len(self.views)} method={self.method}")


def view_data(det: Detection, target: Target, origin: tuple[float, float], max_points: int,
              use_corners: bool) -> ViewData:
    """Flatten a detection into refinement observations (edge points subsampled evenly; a view
    with checkerboard corners only has no edge rows)."""
    pts, ctr, rad, sgn, ids = [np.zeros((0, 2))], [np.zeros((0, 2))], [np.zeros(0)], [np.zeros(0, int)], \
        [np.zeros(0, int)]
    for e in det.edges:
        c = target.circles[e.circle]
        p = e.points
        if len(p) > max_points:
            p = p[np.linspace(0, len(p), max_points, endpoint=False).astype(int)]
        pts.append(p)
        ctr.append(np.tile([c.center[0] - origin[0], c.center[1] - origin[1]], (len(p), 1)))
        rad.append(np.full(len(p), c.radius))
        sgn.append(np.full(len(p), 1 if c.dark_inside else -1))
        ids.append(np.full(len(p), e.circle))
    vd = ViewData(np.concatenate(pts), np.concatenate(ctr), np.concatenate(rad), np.concatenate(sgn),
                  np.concatenate(ids))
    if use_corners and det.corners is not None and target.checkerboard is not None:
        ok = np.all(np.isfinite(det.corners), 1)  # corners the detector's check rejected are NaN
        vd.corners = det.corners[ok]
        vd.corner_obj = target.checkerboard.corner_points()[ok] - np.array(origin)
    return vd


def calibrate(dets: list[Detection], target: Target, options: CalibrationOptions = CalibrationOptions()
              ) -> CalibrationResult:
    """Calibrate from detections (one per view, rejected ones included for the report): checked
    options and views, a closed-form start (circular points, grid homographies, or OpenCV's
    calibration of checkerboard corners), the refinement (outlier observations and views dropped),
    views that had no start posed with the refined camera and added, the target's shape if asked
    for."""
    opt = _checked_options(options, target)
    reports, usable = _checked_views(dets, opt)
    w, h = dets[0].width, dets[0].height
    lens = DISTORTION_CHOICES[opt.distortion][0]
    if opt.method == "zhang":
        if not opt.refine:
            return _zhang(dets, target, opt, reports, w, h)
        start = zhang_start(dets, usable, target, opt, reports)
    else:
        start = closed_form_start(dets, usable, target, opt, reports)
    if not opt.refine:
        if lens.wide:
            raise CalibrationError("the equidistant (fisheye) model needs the refinement: drop --no-refine")
        for k in start.used:
            reports[k].used = True
        return CalibrationResult(K=start.sol.K, D=np.zeros(5), width=w, height=h, method=opt.method, rms=float("nan"),
                                 std={}, degeneracy_ratio=start.sol.degeneracy_ratio, views=reports,
                                 warnings=start.warnings, K_initial=start.sol.K, refined=False, distortion_model="none",
                                 std_model="none: the closed form has no covariance")
    origin = target.local_origin
    dof = 6 if (len({c.center for c in target.circles}) > 1 or target.checkerboards) else 5
    views, poses0, idx = _start_poses(dets, start, target, opt, reports, origin, dof)
    if len(idx) < opt.min_views:
        raise CalibrationError(f"only {len(idx)} view(s) gave a pose; need {opt.min_views}")
    D0 = _start_distortion(dets, start, opt, lens.n, w, h)
    res = _refine(views, start.sol.K, D0, poses0, dof, opt)
    res, idx = _drop_outlier_views(res, idx, reports, opt, dof)
    res, idx = _add_views_without_start(res, idx, dets, usable, target, opt, reports, origin, dof)
    warnings = list(start.warnings)
    shape_effect: dict[str, float] = {}
    if opt.target_shape:
        res, shape_effect = _estimate_target_shape(res, target, opt, origin, dof)
        warnings += _shape_warnings(res.shape, res.shape_std, shape_effect, res)
    if not np.all(np.isfinite(res.K)) or res.K[0, 0] <= 0 or res.K[1, 1] <= 0:
        raise CalibrationError("refinement diverged; check the target file matches the printed target")
    _report_views(res, idx, dets, reports)
    _check_result(res, w, h, warnings)
    if not lens.wide:
        _refuse_beyond_pinhole_field([dets[k] for k in usable], target, lens, w, h, res.K[0, 0])
    folded = _check_model_fits(res, lens, w, h)
    if not lens.wide and res.rms > MISFIT_RMS:
        _refuse_if_fisheye_fits(dets, target, opt, res.rms)
    if folded > 0:
        warnings.append(f"{100 * folded:.3f} % of the edge points lie where the fitted {lens.name} model folds over "
                        "(the image's rim): the model does not hold there; a richer model may")
    views = res.views
    return CalibrationResult(
        K=res.K, D=res.D, width=w, height=h, method=opt.method, rms=res.rms, std=res.std,
        degeneracy_ratio=start.sol.degeneracy_ratio, views=reports, warnings=warnings, K_initial=start.sol.K,
        refined=True, distortion_model=opt.distortion, poses=res.poses, edge_points=[v.points for v in views],
        edge_residuals=res.residuals, edge_circles=[v.circle_ids for v in views],
        circle_names=[c.feature for c in target.circles], shape=res.shape if opt.target_shape else {},
        shape_std=res.shape_std, shape_effect=shape_effect, projection=_projection(res, w, h, opt.projection_distance),
        refinement=res, corner_points=[v.corners for v in views], corner_residuals=res.corner_residuals,
        std_model=std_model(res)).with_model_bias_warning()


def std_model(res: RefineResult) -> str:
    """What the standard deviations of a refinement are, in words (report.json's ``std_model``)."""
    loss = "soft-L1 (robust)" if res.robust else "least-squares"
    kinds = []
    if res.problem is not None and res.problem.n_edge:
        kinds.append(f"edge points kappa {res.kappa[0]:.2f}")
    if res.problem is not None and res.problem.n_corner:
        kinds.append(f"corners kappa {res.kappa[1]:.2f}")
    return (f"sandwich covariance of the {loss} M-estimator (psi' in the bread, psi^2 in the meat), per-view noise, "
            f"correlated residuals ({', '.join(kinds)}), outliers removed")


def _refine(views: list[ViewData], K0: np.ndarray, D0: np.ndarray, poses0: list[np.ndarray], dof: int,
            opt: CalibrationOptions, **shape: Any) -> RefineResult:
    """:func:`refine` with the options' distortion, skew, offsets, loss and outlier rejection."""
    return refine(views, K0, D0, poses0, dof, opt.distortion, opt.zero_skew, opt.edge_offsets,
                  loss_scale=LOSS_SCALES[opt.loss], outlier_k=opt.outlier_k, **shape)


LOSS_SCALES = {"soft_l1": 0.3, "linear": float("inf")}  # px; inf: least squares


def _report_views(res: RefineResult, idx: list[int], dets: list[Detection], reports: list[ViewReport]) -> None:
    """Mark the refined views used, with their RMS, edge offset and the observations left out."""
    for j, k in enumerate(idx):
        rep, v = reports[k], res.views[j]
        rep.used, rep.reason = True, ""
        rep.rms, rep.edge_offset = float(res.view_rms[j]), float(res.offsets[j])
        rep.rejected_edges, rep.rejected_corners = v.rejected_edges, v.rejected_corners
        c = dets[k].corners
        rep.unmeasured_corners = int(np.sum(~np.all(np.isfinite(c), 1))) if c is not None else 0


def _projection(res: RefineResult, w: int, h: int, distance: float | None = None) -> ProjectionUncertainty | None:
    """The projection uncertainty of a refinement (None if its covariance is unknown)."""
    if res.covariance is None or res.x is None:
        return None
    out = res.projection_uncertainty(w, h, distance)
    out.default_distance = distance is None
    return out


def _checked_options(options: CalibrationOptions, target: Target) -> CalibrationOptions:
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
    if opt.target_shape and not (target.grids or target.checkerboards):
        raise CalibrationError(f"the shape of target {target.name!r} cannot be estimated: it needs features spread "
                               "over the sheet (a ring or disc grid, or a checkerboard)")
    if opt.target_shape and not opt.refine:
        raise CalibrationError("the target shape is estimated by the refinement; drop --target-shape or --no-refine")
    if opt.loss not in LOSS_SCALES:
        raise CalibrationError(f"unknown loss {opt.loss!r}; choose one of {', '.join(LOSS_SCALES)}")
    if not opt.outlier_k >= 0:
        raise CalibrationError(f"the outlier threshold must be 0 (off) or positive, not {opt.outlier_k}")
    d = opt.projection_distance
    if d is not None and not d > 0:
        raise CalibrationError(f"the projection uncertainty's distance must be positive (or inf), not {d}")
    return opt


def _checked_views(dets: list[Detection], opt: CalibrationOptions) -> tuple[list[ViewReport], list[int]]:
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


@dataclass
class ClosedFormStart:
    """What the closed form gave: K and its degeneracy figures, the views it used (indices into
    the session), per-view grid poses when it has them, the detections it ran on (drawn without
    distortion where the lens needs it), the plumb-line division parameter."""

    sol: Any
    used: list[int]
    grid_poses: dict[int, Any]
    init_dets: list[Detection]
    division: float
    warnings: list[str]
    D: np.ndarray | None = None  # the start's distortion when it has one (OpenCV's checkerboard calibration)


def zhang_start(dets: list[Detection], usable: list[int], target: Target, opt: CalibrationOptions,
                reports: list[ViewReport]) -> ClosedFormStart:
    """K, D and a pose per view from OpenCV's calibration of the checkerboard corners (Zhang's
    closed form and OpenCV's own refinement): the start of the checkerboard path."""
    try:
        z = calibrate_zhang([dets[k] for k in usable], target, opt.distortion, target.local_origin)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    used = [usable[k] for k in z.used]
    for k in usable:
        if k not in used:
            reports[k].used, reports[k].reason = False, "zhang: fewer than 6 measured corners"
    Ki = np.linalg.inv(z.K)
    sol = IacSolution(z.K, Ki.T @ Ki, float("nan"))
    return ClosedFormStart(sol, used, dict(zip(used, z.poses, strict=True)), dets, 0.0, [], z.D)


def closed_form_start(dets: list[Detection], usable: list[int], target: Target, opt: CalibrationOptions,
                      reports: list[ViewReport]) -> ClosedFormStart:
    """K from the circular points (or grid homographies) of the usable views. Strong distortion
    is taken out first: a fisheye's edges are drawn in the virtual pinhole camera of a generic
    equidistant lens, a grid's rows are straightened by a division model (plumb line)."""
    lens = DISTORTION_CHOICES[opt.distortion][0]
    good = [dets[k] for k in usable]
    lam = 0.0
    init_dets = dets
    if lens.wide:
        init_dets = virtual_pinhole_detections(dets, equidistant_focal(good, target))
    elif target.grids and opt.distortion != "none":
        # grids are used with strongly distorting lenses: straighten the rows first (plumb line)
        lam = division_parameter(good, target)
        init_dets = undistort_detections(dets, lam)
    good = [init_dets[k] for k in usable]
    grid_poses: dict[int, Any] = {}
    try:
        if opt.method == "grid":
            sol, poses = grid_homography_init(good, target, target.local_origin, opt.zero_skew)
            used_local = [k for k, p in enumerate(poses) if p is not None]
            failed = {k: "fewer than 6 grid elements" for k, p in enumerate(poses) if p is None}
            grid_poses = {usable[k]: p for k, p in enumerate(poses) if p is not None}
        else:
            sol, used_local, failed = intrinsics_closed_form(good, target, opt.method, opt.zero_skew)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k_local, why in failed.items():
        rep = reports[usable[k_local]]
        rep.used, rep.reason = False, f"{opt.method}: {why}"
    return ClosedFormStart(sol, [usable[k] for k in used_local], grid_poses, init_dets, lam,
                           [sol.warning] if sol.warning else [])


def _start_poses(dets: list[Detection], start: ClosedFormStart, target: Target, opt: CalibrationOptions,
                 reports: list[ViewReport], origin: tuple[float, float], dof: int
                 ) -> tuple[list[ViewData], list[np.ndarray], list[int]]:
    """Observations and start pose of every view the closed form used."""
    lens = DISTORTION_CHOICES[opt.distortion][0]
    views, poses0, idx = [], [], []
    for k in start.used:
        try:
            if k in start.grid_poses:
                pose = start.grid_poses[k]
            elif target.grids:
                pose = pose_from_circles(start.init_dets[k], target, start.sol.K, origin)
            else:
                pose = pose_from_view(start.init_dets[k] if lens.wide else dets[k], target, start.sol.K, origin)
        except (CircularPointError, np.linalg.LinAlgError) as exc:
            reports[k].used, reports[k].reason = False, f"pose: {exc}"
            continue
        views.append(observations(dets[k], target, origin, opt))
        poses0.append(pose_to_params(pose, dof))
        idx.append(k)
    return views, poses0, idx


def observations(det: Detection, target: Target, origin: tuple[float, float], opt: CalibrationOptions) -> ViewData:
    """:func:`view_data` with the options' budget of points per edge and per view."""
    n_edges = max(len(det.edges), 1)
    per_edge = max(8, min(opt.max_points_per_edge, opt.max_points_per_view // n_edges))
    return view_data(det, target, origin, per_edge, opt.use_corners)


def _start_distortion(dets: list[Detection], start: ClosedFormStart, opt: CalibrationOptions, n: int, w: int,
                      h: int) -> np.ndarray:
    """The start's own D, zero, or k1 (k2) of the plumb-line division model when grids were straightened."""
    D0 = np.zeros(n)
    if start.D is not None:
        D0[: min(n, len(start.D))] = start.D[:n]
        return D0
    if start.division and "k1" in DISTORTION_MODELS[opt.distortion]:
        r_max = max(float(np.max(np.hypot(*(e.points - [w / 2, h / 2]).T))) for k in start.used for e in dets[k].edges)
        f = float(np.sqrt(start.sol.K[0, 0] * start.sol.K[1, 1]))
        D0[0], D0[1] = plumb_bob_from_division(start.division, f, r_max, "k2" in DISTORTION_MODELS[opt.distortion])
    return D0


def _drop_outlier_views(res: RefineResult, idx: list[int], reports: list[ViewReport], opt: CalibrationOptions,
                        dof: int) -> tuple[RefineResult, list[int]]:
    """Drop views whose RMS exceeds ``outlier_factor`` times the median (moved during exposure,
    wrong detection) and refit once."""
    med = float(np.median(res.view_rms))
    bad = [i for i, r in enumerate(res.view_rms) if r > opt.outlier_factor * max(med, 0.02)]
    if not bad or len(idx) - len(bad) < opt.min_views:
        return res, idx
    for i in bad:
        what = "edge RMS" if len(res.views[i].points) else "corner RMS"
        reports[idx[i]].used = False
        reports[idx[i]].reason = (f"outlier: {what} {res.view_rms[i]:.3f} px is "
                                  f"{res.view_rms[i] / max(med, 1e-9):.1f}x the median {med:.3f} px")
    keep = [i for i in range(len(idx)) if i not in bad]
    res = _refine([res.views[i] for i in keep], res.K, res.D, [res.poses[i] for i in keep], dof, opt)
    return res, [idx[i] for i in keep]


def _add_views_without_start(res: RefineResult, idx: list[int], dets: list[Detection], usable: list[int],
                             target: Target, opt: CalibrationOptions, reports: list[ViewReport],
                             origin: tuple[float, float], dof: int) -> tuple[RefineResult, list[int]]:
    """Views the closed form could not use (a fisheye's rim, a view whose conics the start could
    not solve) or that were dropped as outliers (possibly a bad start) are posed with the refined
    camera (:func:`pose_with_camera`) and the refinement is repeated with them; a view that still
    fits badly is dropped as an outlier again."""
    missing = [k for k in usable if k not in idx]  # an outlier may only have had a bad start: one more try
    if not missing:
        return res, idx
    cam = Camera(res.K, res.D, dets[0].width, dets[0].height, res.model)
    new_views, new_poses, new_idx = [], [], []
    for k in missing:
        try:
            pose = pose_with_camera(dets[k], target, cam, origin)
        except (CircularPointError, np.linalg.LinAlgError, ValueError) as exc:
            reports[k].reason = f"{reports[k].reason}; pose with the refined camera: {exc}"
            continue
        new_views.append(observations(dets[k], target, origin, opt))
        new_poses.append(pose_to_params(pose, dof))
        new_idx.append(k)
    if not new_idx:
        return res, idx
    idx = idx + new_idx
    res = _refine(res.views + new_views, res.K, res.D, [*res.poses, *new_poses], dof, opt)
    return _drop_outlier_views(res, idx, reports, opt, dof)


def _estimate_target_shape(res: RefineResult, target: Target, opt: CalibrationOptions,
                           origin: tuple[float, float], dof: int) -> tuple[RefineResult, dict[str, float]]:
    """Refit with the sheet's shape free; the effect on the intrinsics against the flat fit."""
    flat = res
    res = _refine(flat.views, flat.K, flat.D, flat.poses, dof, opt, shape=opt.target_shape,
                  shape_frame=target_shape_frame(target, origin))
    effect = {"fx": res.K[0, 0] - flat.K[0, 0], "fy": res.K[1, 1] - flat.K[1, 1],
              "cx": res.K[0, 2] - flat.K[0, 2], "cy": res.K[1, 2] - flat.K[1, 2], "rms_flat": flat.rms}
    if "pitch_ratio" in res.shape_std:
        effect["pitch_aspect_correlation"] = res.pitch_aspect_correlation
    return res, effect


def target_shape_frame(target: Target, origin: tuple[float, float]) -> tuple[float, float, float, float]:
    """Frame of the warp (refine.shape_frame_of) over all circle centres and checkerboard corners
    of the target, in the refinement's local frame (origin: ``Target.local_origin``)."""
    pts = [np.array([c.center for c in target.circles]).reshape(-1, 2)]
    if target.checkerboard is not None:
        pts.append(target.checkerboard.corner_points())
    return shape_frame_of(np.concatenate(pts) - np.array(origin))


def _shape_warnings(shape: dict[str, float], std: dict[str, float], effect: dict[str, float],
                    res: RefineResult) -> list[str]:
    """Say when the estimated shape matters: significant (> 3 sigma) and moving an intrinsic by
    more than its own standard deviation."""
    out = []
    if "pitch_ratio" in std and abs(res.pitch_aspect_correlation) > 0.9:
        out.append(f"the pitch ratio and fy/fx are {abs(res.pitch_aspect_correlation):.2f} correlated: these views "
                   "cannot tell a print scaled in y from non-square pixels; tilt the target more about both axes, or "
                   "measure the print and estimate the warp only")
    significant = [n for n in shape if n in std and abs(shape[n]) > 3 * std[n]]
    moved = [k for k in ("fx", "fy", "cx", "cy") if abs(effect[k]) > max(res.std.get(k, 0.0), 1e-9)]
    if not significant or not moved:
        return out
    what = []
    if "pitch_ratio" in significant:
        what.append(f"y printed {100 * shape['pitch_ratio']:+.3f} % against x")
    warps = [f"{n} {1000 * shape[n]:+.2f} mm" for n in ("warp_x", "warp_y") if n in significant]
    if warps:
        what.append("sheet not flat (" + ", ".join(warps) + ")")
    moves = ", ".join(f"{k} {effect[k]:+.2f} px" for k in moved)
    return [*out, f"target shape matters: {'; '.join(what)}; against a flat, true-to-scale sheet it moves {moves}"]


MISFIT_RMS = 0.5  # px of edge RMS above which a pinhole model is checked against a fisheye one


PINHOLE_MAX_FIELD_DEG = 85.0  # rays this far from the axis are beyond what an x/z model can describe
PINHOLE_CHECK_RATIO = 0.7  # the field is estimated only when the edges reach r > 0.7 fx of the fit


def _refuse_beyond_pinhole_field(usable: list[Detection], target: Target, lens: LensModel, w: int, h: int,
                                 fx: float) -> None:
    """A pinhole model (x = X/Z) cannot describe rays near or beyond 90 degrees, but fitted to a
    fisheye it may still reach a small RMS in one of several minima (which one was seen to change
    with the BLAS kernel, as was whether it drops the views at the rim as outliers). The field
    every usable view covers is estimated independently of the fit, with the generic fisheye lens
    r = f theta of :func:`equidistant_focal`; a field wider than PINHOLE_MAX_FIELD_DEG is refused."""
    if not any(d.edges for d in usable):
        return  # corners only: the fold check (_check_model_fits) covers them
    pts = np.concatenate([e.points for d in usable for e in d.edges])
    r = np.hypot(pts[:, 0] - w / 2, pts[:, 1] - h / 2)
    r_far = float(np.percentile(r, 99.9))
    if r_far < PINHOLE_CHECK_RATIO * fx:
        return  # the fitted pinhole itself puts every edge within ~35 degrees: nothing to check
    # a rough f is all this needs: a quarter of the edge points of at most 12 views
    sparse = [replace(d, edges=[replace(e, points=e.points[::4]) for e in d.edges])
              for d in usable[:: max(1, len(usable) // 12)]]
    field = float(np.degrees(r_far / equidistant_focal(sparse, target)))
    if field > PINHOLE_MAX_FIELD_DEG:
        raise CalibrationError(f"the views see rays up to about {field:.0f} degrees from the optical axis (estimated "
                               f"with a generic fisheye lens); a {lens.name} model (x/z) cannot describe rays near "
                               "or beyond 90 degrees: use --distortion equidistant (fisheye)")


def _refuse_if_fisheye_fits(dets: list[Detection], target: Target, opt: CalibrationOptions, rms: float) -> None:
    """A pinhole polynomial fitted to a fisheye does not fold, it just fits badly: when the edge
    RMS is high, the equidistant model is tried on the same views; if it fits three times better
    the result is refused and the model named, rather than a camera that is wrong everywhere."""
    try:
        fish = calibrate(dets, target, replace(opt, distortion="equidistant"))
    except CalibrationError:
        return
    if fish.rms < rms / 3:
        raise CalibrationError(f"the {opt.distortion} model does not fit this lens (edge RMS {rms:.2f} px); the "
                               f"equidistant (fisheye) model fits the same views with {fish.rms:.3f} px: use "
                               "--distortion equidistant (node: distortion_model equidistant)")


# a fitted model that folds over under more than this share of the observed edge points is refused
# (a fit whose optimum lies in a flat valley, as a rational model on a fisheye, may fold more or less
# depending on the last bits: any such fold is a model that does not describe the lens)
FOLD_REFUSE_FRACTION = 0.0005


def _check_model_fits(res: RefineResult, lens: LensModel, w: int, h: int) -> float:
    """A pinhole polynomial fitted to a lens wider than it can describe folds over: some observed
    edge points then have no ray (or not the one they came from). Refuse such a result and name
    the model to use, rather than publish a folded-over camera."""
    cam = Camera(res.K, res.D, w, h, lens.name)
    ok, _ = consistent_rays(cam, np.concatenate([np.r_[v.points, v.corners] for v in res.views]), 0.05)
    bad = float(np.mean(~ok))
    if bad > FOLD_REFUSE_FRACTION:
        field = float(np.degrees(lens.max_angle(res.D)))
        advice = ("use --distortion equidistant (fisheye)" + (", or rational_polynomial for a wide-angle lens"
                                                              if lens.name == "plumb_bob" else "")
                  if not lens.wide else "check that the views show this target")
        raise CalibrationError(f"the fitted {lens.name} model folds over inside the observed field ({100 * bad:.1f} % "
                               "of the edge points and corners have no consistent ray; the model is monotonic "
                               f"only up to {field:.0f} degrees): this lens is wider than {lens.name} can describe; "
                               f"{advice}")
    return bad


def _check_result(res: RefineResult, w: int, h: int, warnings: list[str]) -> None:
    K = res.K
    if not (0 < K[0, 2] < w and 0 < K[1, 2] < h):
        raise CalibrationError(f"principal point ({K[0, 2]:.0f}, {K[1, 2]:.0f}) outside the image: the "
                               "views do not constrain the camera; add tilted views across the image")
    if res.rms > 1.0:
        warnings.append(f"edge RMS {res.rms:.2f} px is high: check focus, motion blur, target flatness")
    if not res.success:
        warnings.append(f"refinement stopped early: {res.message}")


def _zhang(dets: list[Detection], target: Target, opt: CalibrationOptions, reports: list[ViewReport], w: int, h: int
           ) -> CalibrationResult:
    """OpenCV's answer as it stands (``--method zhang --no-refine``: the baseline), with its
    i.i.d. standard deviations and its corner residuals for the report."""
    try:
        z = calibrate_zhang(dets, target, opt.distortion)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k, rep in enumerate(reports):
        rep.used = k in z.used
        if dets[k].ok and not rep.used:
            rep.reason = "checkerboard not found"
    names = [n for n in intrinsic_names(DISTORTION_CHOICES[opt.distortion][0]) if n != "skew"]
    assert target.checkerboard is not None
    grid = np.c_[target.checkerboard.corner_points(), np.zeros(len(target.checkerboard.corner_points()))]
    cam = Camera(z.K, z.D, w, h, DISTORTION_CHOICES[opt.distortion][0].name)
    corners, residuals = [], []
    for k, pose in zip(z.used, z.poses, strict=True):
        c = np.asarray(dets[k].corners, float)
        ok = np.all(np.isfinite(c), 1)
        corners.append(c[ok])
        residuals.append(c[ok] - cam.project(grid[ok] @ pose.R.T + pose.t))
    std = {n: float(s) for n, s in zip(names, z.std, strict=False) if np.isfinite(s)}
    res = CalibrationResult(K=z.K, D=z.D, width=w, height=h, method="zhang", rms=z.rms, std=std,
                            degeneracy_ratio=float("nan"), views=reports, refined=True,
                            distortion_model=opt.distortion, edge_points=[np.zeros((0, 2)) for _ in corners],
                            edge_residuals=[np.zeros(0) for _ in corners],
                            edge_circles=[np.zeros(0, int) for _ in corners], corner_points=corners,
                            corner_residuals=residuals,
                            std_model=("OpenCV calibrateCamera's standard deviations: independent corner noise of "
                                       "one variance (the RMS), no correlation, no outlier rejection"
                                       if std else "none: OpenCV's fisheye calibration gives no covariance"))
    return res.with_model_bias_warning()


def _rejection_summary(reports: list[ViewReport]) -> str:
    reasons: dict[str, int] = {}
    for r in reports:
        if r.reason:
            reasons[r.reason] = reasons.get(r.reason, 0) + 1
    if not reasons:
        return ""
    return "Rejected: " + "; ".join(f"{n} x {why}" for why, n in sorted(reasons.items(), key=lambda x: -x[1]))
