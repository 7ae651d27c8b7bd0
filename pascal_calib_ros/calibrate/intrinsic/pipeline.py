"""Views -> closed-form initialisation -> joint refinement -> :class:`CalibrationResult`.

A failure is a :class:`CalibrationError` whose message a user can act on; per-view problems are
kept as reasons beside the views rather than raised.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...detect import Detection
from ...geometry import DISTORTION_CHOICES, Camera, CircularPointError, DegenerateViewsError, ImageSize
from ...targets import Target
from ..solver.observations import ViewData
from ..solver.problem import DISTORTION_MODELS, intrinsic_names, shape_frame_of
from ..solver.refine import RefineResult, refine
from .checks import (
    MISFIT_RMS,
    BeyondPinholeFieldError,
    check_model_fits,
    check_result,
    refuse_beyond_pinhole_field,
    shape_warnings,
)
from .initial import (
    CIRCLE_METHODS,
    pose_to_params,
    pose_with_camera,
)
from .options import LOSS_SCALES, CalibrationOptions, checked_options, checked_views, observations
from .result import CalibrationError, CalibrationResult, ViewReport
from .start import (
    RESTART_KAPPAS,
    DegenerateStartError,
    closed_form_start,
    division_start,
    restart_order,
    start_distortion,
    start_poses,
    zhang_start,
)
from .zhang import calibrate_zhang

DEFAULT_OPTIONS = CalibrationOptions()


def calibrate(dets: list[Detection], target: Target, options: CalibrationOptions = DEFAULT_OPTIONS
              ) -> CalibrationResult:
    """Calibrate from detections (one per view, rejected ones included for the report): checked
    options and views, a closed-form start (circular points, grid homographies, or OpenCV's
    calibration of checkerboard corners; for circles under strong distortion, restarts from
    division-model starts: :func:`cold_calibration`), the refinement (outlier observations and
    views dropped), views that had no start posed with the refined camera and added, the target's
    shape if asked for."""
    return cold_calibration(dets, target, options)[0]


@dataclass
class Prepared:
    """The checked options, a report per view and the indices of the usable views."""

    opt: CalibrationOptions
    reports: list[ViewReport]
    usable: list[int]


def prepare(dets: list[Detection], target: Target, options: CalibrationOptions) -> Prepared:
    """The options checked against the target and the views checked (a CalibrationError if they cannot work)."""
    opt = checked_options(options, target)
    reports, usable = checked_views(dets, opt)
    return Prepared(opt, reports, usable)


def cold_calibration(dets: list[Detection], target: Target, options: CalibrationOptions
                     ) -> tuple[CalibrationResult, Prepared, Refined | None]:
    """The calibration from the closed-form start, its checked views and its first refinement
    (None without refinement). When that start fails (w not positive definite, a refused or folded
    model; not views too few or too parallel for w, nor a field too wide for a pinhole) or ends
    with an edge RMS above MISFIT_RMS, and the lens may be the cause (:func:`restartable`), the
    calibration is restarted from division-model starts (:func:`restarted`) and the better fit is
    kept; a result the plain start gives and that fits is never touched."""
    prep = prepare(dets, target, options)
    try:
        first = first_refinement(dets, target, prep)
        if isinstance(first, CalibrationResult):
            return first, prep, None
        cal = finish(dets, target, prep, first)
    except (DegenerateStartError, BeyondPinholeFieldError):
        raise  # the views' geometry or the lens's field: another start would only hide it
    except CalibrationError:
        if not restartable(prep.opt, target):
            raise
        again = restarted(dets, target, options, float("inf"))
        if again is None:
            raise
        return again
    if cal.rms <= MISFIT_RMS or not restartable(prep.opt, target):
        return cal, prep, first
    return restarted(dets, target, options, cal.rms) or (cal, prep, first)


def restartable(opt: CalibrationOptions, target: Target) -> bool:
    """Whether a failed start may be the lens's fault and :func:`restarted` can help: a circle
    method's closed form (not grids, which straighten their rows first, nor a fisheye, drawn in a
    virtual pinhole camera) with a radial distortion to refine."""
    lens = DISTORTION_CHOICES[opt.distortion][0]
    return (opt.refine and opt.method in CIRCLE_METHODS and not target.grids and not lens.wide
            and "k1" in DISTORTION_MODELS[opt.distortion])


RESTART_FINISHES = 3  # restarted starts carried through the checks, in :func:`.start.restart_order`


def restarted(dets: list[Detection], target: Target, options: CalibrationOptions, rms_to_beat: float
              ) -> tuple[CalibrationResult, Prepared, Refined] | None:
    """The calibration from the division-model starts (:func:`.start.division_start`): each start
    refined, the first refinements ranked by :func:`.start.restart_order` (their robust cost over
    the same observations; fits the noise cannot tell apart by their extrapolation to the image
    corners) and carried through :func:`finish` in that order until one passes its checks with an
    edge RMS below ``rms_to_beat``; None if none does. All of them minimise the same cost over the
    same observations before their outlier rejection; the starts differ only in which minimum they
    reach (on a single ring through a wide lens, minima whose distortion differs mostly in the
    unobserved image corners)."""
    firsts: list[tuple[Prepared, Refined]] = []
    for kappa in RESTART_KAPPAS:
        prep = prepare(dets, target, options)
        try:
            first = first_refinement(dets, target, prep, kappa)
        except CalibrationError:
            continue
        if isinstance(first, Refined) and np.isfinite(first.res.rms):
            firsts.append((prep, first))
    order = restart_order([(first.res, first.idx) for _, first in firsts], dets[0].size)
    for i in order[:RESTART_FINISHES]:
        prep, first = firsts[i]
        try:
            cal = finish(dets, target, prep, first)
        except CalibrationError:
            continue
        if cal.rms < rms_to_beat:
            return cal, prep, first
    return None


def first_refinement(dets: list[Detection], target: Target, prep: Prepared, kappa: float | None = None
                     ) -> Refined | CalibrationResult:
    """The closed-form start and the first refinement of the views it posed; the calibration itself
    when there is no refinement (``--no-refine``, OpenCV's answer as it stands). ``kappa``: the
    circle methods' start from edges undistorted by that division model (:func:`.start.division_start`)."""
    opt, reports, usable = prep.opt, prep.reports, prep.usable
    w, h = dets[0].width, dets[0].height
    lens = DISTORTION_CHOICES[opt.distortion][0]
    if opt.method == "zhang":
        if not opt.refine:
            return _zhang(dets, target, opt, reports, ImageSize(w, h))
        start = zhang_start(dets, usable, target, opt, reports)
    elif kappa is not None:
        start = division_start(dets, usable, target, opt, reports, kappa)
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
    dof = pose_dof(target)
    views, poses0, idx = start_poses(dets, start, target, opt, reports, target.local_origin, dof)
    if len(idx) < opt.min_views:
        raise CalibrationError(f"only {len(idx)} view(s) gave a pose; need {opt.min_views}")
    D0 = start_distortion(dets, start, opt, lens.n, ImageSize(w, h))
    res = refine_prepared(views, start.sol.K, D0, poses0, dof, opt)
    return Refined(res, idx, start.sol.K, start.sol.degeneracy_ratio, list(start.warnings))


def pose_dof(target: Target) -> int:
    """Parameters of a view's pose: 6, or 5 for a target with a single circle centre (its rotation
    about the ring's axis unobservable)."""
    return 6 if (len({c.center for c in target.circles}) > 1 or target.boards) else 5


@dataclass
class Refined:
    """A first refinement of the session and what the result reports of its start: the refinement,
    the session's index of each of its views, the closed form's K, its degeneracy figure and
    warnings."""

    res: RefineResult
    idx: list[int]
    K_initial: np.ndarray
    degeneracy_ratio: float
    start_warnings: list[str]


def finish(dets: list[Detection], target: Target, prep: Prepared, first: Refined) -> CalibrationResult:
    """The calibration from a first refinement: outlier views dropped, views without a start posed
    with the refined camera and added, the target's shape if asked for, the checks of the result.
    The result's refinement is ``first.res`` itself when none of these refitted."""
    opt, reports, usable = prep.opt, prep.reports, prep.usable
    w, h = dets[0].width, dets[0].height
    lens = DISTORTION_CHOICES[opt.distortion][0]
    origin, dof = target.local_origin, pose_dof(target)
    res, idx = _drop_outlier_views(first.res, first.idx, reports, opt, dof)
    res, idx = _add_views_without_start(res, idx, dets, usable, target, opt, reports=reports, origin=origin, dof=dof)
    warnings = list(first.start_warnings)
    shape_effect: dict[str, float] = {}
    if opt.target_shape:
        res, shape_effect = _estimate_target_shape(res, target, opt, origin, dof)
        warnings += shape_warnings(res.shape, res.shape_std, shape_effect, res)
    if not np.all(np.isfinite(res.K)) or res.K[0, 0] <= 0 or res.K[1, 1] <= 0:
        raise CalibrationError("refinement diverged; check the target file matches the printed target")
    _report_views(res, idx, dets, reports)
    check_result(res, ImageSize(w, h), warnings)
    if not lens.wide:
        refuse_beyond_pinhole_field([dets[k] for k in usable], target, lens, ImageSize(w, h), res.K[0, 0],
                                    lambda: _fisheye_field(dets, usable, target, opt))
    folded = check_model_fits(res, lens, ImageSize(w, h))
    if not lens.wide and res.rms > MISFIT_RMS:
        _refuse_if_fisheye_fits(dets, target, opt, res.rms)
    if folded > 0:
        warnings.append(f"{100 * folded:.3f} % of the edge points lie where the fitted {lens.name} model folds over "
                        "(the image's rim): the model does not hold there; a richer model may")
    views = res.views
    return CalibrationResult(
        K=res.K, D=res.D, width=w, height=h, method=opt.method, rms=res.rms, std=res.std,
        degeneracy_ratio=first.degeneracy_ratio, views=reports, warnings=warnings, K_initial=first.K_initial,
        refined=True, distortion_model=opt.distortion, poses=res.poses, edge_points=[v.points for v in views],
        edge_residuals=res.residuals, edge_circles=[v.circle_ids for v in views],
        circle_names=[c.feature for c in target.circles], shape=res.shape if opt.target_shape else {},
        shape_std=res.shape_std, shape_effect=shape_effect, refinement=res, corner_points=[v.corners for v in views],
        corner_residuals=res.corner_residuals, std_model=std_model(res))


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


def refine_prepared(views: list[ViewData], K0: np.ndarray, D0: np.ndarray, poses0: list[np.ndarray], dof: int,
            opt: CalibrationOptions, **more: Any) -> RefineResult:
    """:func:`refine` with the options' distortion, skew, offsets, loss and outlier rejection (``more``:
    its further keywords)."""
    return refine(views, K0, D0, poses0, dof, opt.distortion, opt.zero_skew, opt.edge_offsets,
                  loss_scale=LOSS_SCALES[opt.loss], outlier_k=opt.outlier_k, **more)


def _report_views(res: RefineResult, idx: list[int], dets: list[Detection], reports: list[ViewReport]) -> None:
    """Mark the refined views used, with their RMS, edge offset and the observations left out."""
    for j, k in enumerate(idx):
        rep, v = reports[k], res.views[j]
        rep.used, rep.reason = True, ""
        rep.rms, rep.edge_offset = float(res.view_rms[j]), float(res.offsets[j])
        rep.rejected_edges, rep.rejected_corners = v.rejected_edges, v.rejected_corners
        c = dets[k].corners
        rep.unmeasured_corners = int(np.sum(~np.all(np.isfinite(c), 1))) if c is not None else 0
        if dets[k].marker_ids is not None and c is not None:  # NaN rows: corners out of view, too
            rep.unmeasured_corners = dets[k].corners_rejected
            rep.board_corners = (int(np.all(np.isfinite(c), 1).sum()), len(c))


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
    res = refine_prepared([res.views[i] for i in keep], res.K, res.D, [res.poses[i] for i in keep], dof, opt)
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
    # in session order, as the result's views are reported (the report pairs them by position)
    order = np.argsort(idx + new_idx, kind="stable")
    views, poses = res.views + new_views, [*res.poses, *new_poses]
    idx = [(idx + new_idx)[i] for i in order]
    res = refine_prepared([views[i] for i in order], res.K, res.D, [poses[i] for i in order], dof, opt)
    return _drop_outlier_views(res, idx, reports, opt, dof)


def _estimate_target_shape(res: RefineResult, target: Target, opt: CalibrationOptions,
                           origin: tuple[float, float], dof: int) -> tuple[RefineResult, dict[str, float]]:
    """Refit with the sheet's shape free; the effect on the intrinsics against the flat fit."""
    flat = res
    res = refine_prepared(flat.views, flat.K, flat.D, flat.poses, dof, opt, shape=opt.target_shape,
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
    if target.board is not None:
        pts.append(target.board.corner_points())
    return shape_frame_of(np.concatenate(pts) - np.array(origin))


def _fisheye_rms(dets: list[Detection], target: Target, opt: CalibrationOptions) -> float:
    """Edge RMS (px) of the equidistant (fisheye) model calibrated on the same views; inf if it fails."""
    try:
        return calibrate(dets, target, replace(opt, distortion="equidistant")).rms
    except CalibrationError:
        return float("inf")


def _fisheye_field(dets: list[Detection], usable: list[int], target: Target, opt: CalibrationOptions) -> float:
    """The angle (degrees) from the optical axis of the farthest edge points (99.9th percentile) under
    the equidistant model calibrated on the same views (rays at and beyond 90 degrees included); NaN
    if that calibration fails."""
    try:
        fish = calibrate(dets, target, replace(opt, distortion="equidistant"))
    except CalibrationError:
        return float("nan")
    rays = fish.camera().unproject(np.concatenate([e.points for k in usable for e in dets[k].edges]))
    rays = rays[np.all(np.isfinite(rays), 1)]
    if not len(rays):
        return float("nan")
    cos = rays[:, 2] / np.linalg.norm(rays, axis=1)
    return float(np.percentile(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), 99.9))


def _refuse_if_fisheye_fits(dets: list[Detection], target: Target, opt: CalibrationOptions, rms: float) -> None:
    """A pinhole polynomial fitted to a fisheye does not fold, it just fits badly: when the edge
    RMS is high, the equidistant model is tried on the same views; if it fits three times better
    the result is refused and the model named, rather than a camera that is wrong everywhere."""
    fish = _fisheye_rms(dets, target, opt)
    if fish < rms / 3:
        raise CalibrationError(f"the {opt.distortion} model does not fit this lens (edge RMS {rms:.2f} px); the "
                               f"equidistant (fisheye) model fits the same views with {fish:.3f} px: use "
                               "--distortion equidistant (node: distortion_model equidistant)")


def _zhang(dets: list[Detection], target: Target, opt: CalibrationOptions, reports: list[ViewReport], size: ImageSize
           ) -> CalibrationResult:
    """OpenCV's answer as it stands (``--method zhang --no-refine``: the baseline), with its
    i.i.d. standard deviations and its corner residuals for the report."""
    w, h = size
    try:
        z = calibrate_zhang(dets, target, opt.distortion)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k, rep in enumerate(reports):
        rep.used = k in z.used
        if dets[k].ok and not rep.used:
            rep.reason = "checkerboard not found"
    names = [n for n in intrinsic_names(DISTORTION_CHOICES[opt.distortion][0]) if n != "skew"]
    assert target.board is not None
    grid = np.c_[target.board.corner_points(), np.zeros(len(target.board.corner_points()))]
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
    return res


