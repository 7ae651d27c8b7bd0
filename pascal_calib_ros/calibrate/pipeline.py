"""Views -> closed-form initialisation -> joint refinement -> :class:`CalibrationResult`.

A failure is a :class:`CalibrationError` whose message a user can act on; per-view problems are
kept as reasons beside the views rather than raised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..detect.rings import Detection
from ..geometry.circular import CircularPointError
from ..geometry.iac import DegenerateViewsError
from ..targets import Target
from .initial import (
    CIRCLE_METHODS,
    grid_homography_init,
    intrinsics_closed_form,
    pose_from_circles,
    pose_from_view,
    pose_to_params,
)
from .plumbline import division_parameter, plumb_bob_from_division, undistort_detections
from .refine import (
    DISTORTION_MODELS,
    INTRINSIC_NAMES,
    SHAPE_NAMES,
    RefineResult,
    ViewData,
    refine,
    shape_frame_of,
)
from .zhang import calibrate_zhang

METHODS = (*CIRCLE_METHODS, "grid", "zhang")
MIN_VIEWS = 3


class CalibrationError(ValueError):
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
    distortion_model: str = "plumb_bob"
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

    @property
    def n_used(self) -> int:
        return sum(v.used for v in self.views)

    def summary_line(self) -> str:
        K = self.K
        return (f"fx={K[0, 0]:.2f} fy={K[1, 1]:.2f} cx={K[0, 2]:.2f} cy={K[1, 2]:.2f} "
                f"rms={self.rms:.3f}px views={self.n_used}/{len(self.views)} method={self.method}")


def view_data(det: Detection, target: Target, origin: tuple[float, float], max_points: int,
              use_corners: bool) -> ViewData:
    """Flatten a detection into refinement observations (edge points subsampled evenly)."""
    pts, ctr, rad, sgn, ids = [], [], [], [], []
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
        vd.corners = det.corners
        vd.corner_obj = target.checkerboard.corner_points() - np.array(origin)
    return vd


def calibrate(dets: list[Detection], target: Target, options: CalibrationOptions = CalibrationOptions()
              ) -> CalibrationResult:
    """Calibrate from detections (one per view, rejected ones included for the report)."""
    opt = options
    if not opt.method:
        from dataclasses import replace

        opt = replace(opt, method=target.default_method())
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
    if opt.target_shape and (opt.method == "zhang" or not opt.refine):
        raise CalibrationError("the target shape is estimated by the refinement of the circle methods; "
                               "drop --target-shape or use the target's default method with refinement")
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
    w, h = dets[0].width, dets[0].height
    if opt.method == "zhang":
        return _zhang(dets, target, opt, reports, w, h)
    good = [dets[k] for k in usable]
    lam = 0.0
    init_dets = dets
    if target.grids and opt.distortion != "none":
        # grids are used with strongly distorting lenses: straighten the rows first (plumb line)
        lam = division_parameter(good, target)
        init_dets = undistort_detections(dets, lam)
        good = [init_dets[k] for k in usable]
    grid_poses: list = []
    try:
        if opt.method == "grid":
            sol, grid_poses = grid_homography_init(good, target, target.circles[0].center, opt.zero_skew)
            used_local = [k for k, p in enumerate(grid_poses) if p is not None]
            failed = {k: "fewer than 6 grid elements" for k, p in enumerate(grid_poses) if p is None}
        else:
            sol, used_local, failed = intrinsics_closed_form(good, target, opt.method, opt.zero_skew)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k_local, why in failed.items():
        rep = reports[usable[k_local]]
        rep.used, rep.reason = False, f"{opt.method}: {why}"
    used = [usable[k] for k in used_local]
    warnings = [sol.warning] if sol.warning else []
    if not opt.refine:
        for k in used:
            reports[k].used = True
        return CalibrationResult(sol.K, np.zeros(5), w, h, opt.method, float("nan"), {}, sol.degeneracy_ratio,
                                 reports, warnings, sol.K, False, "none")
    origin = target.circles[0].center
    dof = 6 if (len({c.center for c in target.circles}) > 1 or target.checkerboards) else 5
    views, poses0, idx = [], [], []
    for k in used:
        try:
            if grid_poses:
                pose = grid_poses[usable.index(k)]
            elif target.grids:
                pose = pose_from_circles(init_dets[k], target, sol.K, origin)
            else:
                pose = pose_from_view(dets[k], target, sol.K, origin)
        except (CircularPointError, np.linalg.LinAlgError) as exc:
            reports[k].used, reports[k].reason = False, f"pose: {exc}"
            continue
        n_edges = max(len(dets[k].edges), 1)
        per_edge = max(8, min(opt.max_points_per_edge, opt.max_points_per_view // n_edges))
        views.append(view_data(dets[k], target, origin, per_edge, opt.use_corners))
        poses0.append(pose_to_params(pose, dof))
        idx.append(k)
    if len(idx) < opt.min_views:
        raise CalibrationError(f"only {len(idx)} view(s) gave a pose; need {opt.min_views}")
    D0 = np.zeros(5)
    if lam and "k1" in DISTORTION_MODELS[opt.distortion]:
        r_max = max(float(np.max(np.hypot(*(e.points - [w / 2, h / 2]).T))) for k in used for e in dets[k].edges)
        D0[0], D0[1] = plumb_bob_from_division(lam, float(np.sqrt(sol.K[0, 0] * sol.K[1, 1])), r_max,
                                               "k2" in DISTORTION_MODELS[opt.distortion])
    res = refine(views, sol.K, D0, poses0, dof, opt.distortion, opt.zero_skew, opt.edge_offsets)
    # drop outlier views (moved during exposure, wrong detection) and refit once
    med = float(np.median(res.view_rms))
    bad = [i for i, r in enumerate(res.view_rms) if r > opt.outlier_factor * max(med, 0.02)]
    if bad and len(idx) - len(bad) >= opt.min_views:
        for i in bad:
            reports[idx[i]].used = False
            reports[idx[i]].reason = (f"outlier: edge RMS {res.view_rms[i]:.3f} px is "
                                      f"{res.view_rms[i] / max(med, 1e-9):.1f}x the median {med:.3f} px")
        keep = [i for i in range(len(idx)) if i not in bad]
        views = [views[i] for i in keep]
        idx = [idx[i] for i in keep]
        res = refine(views, res.K, res.D, [res.poses[i] for i in keep], dof, opt.distortion, opt.zero_skew,
                     opt.edge_offsets)
    shape: dict[str, float] = {}
    shape_std: dict[str, float] = {}
    shape_effect: dict[str, float] = {}
    if opt.target_shape:
        frame = target_shape_frame(target, origin)
        flat = res
        res = refine(views, flat.K, flat.D, flat.poses, dof, opt.distortion, opt.zero_skew, opt.edge_offsets,
                     shape=opt.target_shape, shape_frame=frame)
        shape, shape_std = res.shape, res.shape_std
        shape_effect = {"fx": res.K[0, 0] - flat.K[0, 0], "fy": res.K[1, 1] - flat.K[1, 1],
                        "cx": res.K[0, 2] - flat.K[0, 2], "cy": res.K[1, 2] - flat.K[1, 2],
                        "rms_flat": flat.rms}
        if "pitch_ratio" in shape_std:
            shape_effect["pitch_aspect_correlation"] = res.pitch_aspect_correlation
        warnings += _shape_warnings(shape, shape_std, shape_effect, res)
    if not np.all(np.isfinite(res.K)) or res.K[0, 0] <= 0 or res.K[1, 1] <= 0:
        raise CalibrationError("refinement diverged; check the target file matches the printed target")
    for j, k in enumerate(idx):
        reports[k].used = True
        reports[k].rms = float(res.view_rms[j])
        reports[k].edge_offset = float(res.offsets[j])
    _check_result(res, w, h, warnings)
    return CalibrationResult(res.K, res.D, w, h, opt.method, res.rms, res.std, sol.degeneracy_ratio, reports,
                             warnings, sol.K, True, opt.distortion, res.poses, [v.points for v in views],
                             res.residuals, [v.circle_ids for v in views], [c.feature for c in target.circles],
                             shape, shape_std, shape_effect)


def target_shape_frame(target: Target, origin: tuple[float, float]) -> tuple[float, float, float, float]:
    """Frame of the warp (refine.shape_frame_of) over all circle centres and checkerboard corners
    of the target, in the refinement's local frame (origin at the first circle centre)."""
    pts = [np.array([c.center for c in target.circles])]
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
    try:
        K, D, rms, used, std = calibrate_zhang(dets, target, opt.distortion, opt.zero_skew)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k, rep in enumerate(reports):
        rep.used = k in used
        if dets[k].ok and not rep.used:
            rep.reason = "checkerboard not found"
    names = [n for n in INTRINSIC_NAMES if n != "skew"]
    return CalibrationResult(K, D, w, h, "zhang", rms, {n: float(s) for n, s in zip(names, std, strict=False)},
                             float("nan"), reports, [], None, True, opt.distortion)


def _rejection_summary(reports: list[ViewReport]) -> str:
    reasons: dict[str, int] = {}
    for r in reports:
        if r.reason:
            reasons[r.reason] = reasons.get(r.reason, 0) + 1
    if not reasons:
        return ""
    return "Rejected: " + "; ".join(f"{n} x {why}" for why, n in sorted(reasons.items(), key=lambda x: -x[1]))
