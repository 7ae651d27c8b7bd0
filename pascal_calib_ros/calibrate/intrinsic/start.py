"""The closed-form start of a calibration: K (and D) and a pose per view, from the circular points,
the grid homographies, or OpenCV's calibration of checkerboard corners."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...detect import Detection
from ...geometry import (
    DISTORTION_CHOICES,
    Camera,
    CircularPointError,
    DegenerateViewsError,
    IacSolution,
    ImageSize,
    IndefiniteOmegaError,
)
from ...targets import Target
from ..solver.observations import ViewData
from ..solver.problem import DISTORTION_MODELS, SHAPE_NAMES, Problem
from ..solver.refine import RefineResult
from .initial import (
    grid_homography_init,
    intrinsics_closed_form,
    pose_from_circles,
    pose_from_view,
    pose_to_params,
)
from .options import CalibrationOptions, observations
from .plumbline import (
    division_parameter,
    equidistant_focal,
    plumb_bob_from_division,
    undistort_detections,
    virtual_pinhole_detections,
)
from .result import CalibrationError, ViewReport
from .zhang import calibrate_zhang


class DegenerateStartError(CalibrationError):
    """The views' circular points do not determine w (too few views, parallel or fronto-parallel
    planes): a fact about the views' geometry that no other start changes."""


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
    closed form and OpenCV's own refinement): the start of the checkerboard path. A fisheye's corners
    are drawn first in the virtual pinhole camera of a generic equidistant lens (as the circle
    methods' are), and K alone is taken from them: OpenCV's fisheye calibration fails on rays near
    or beyond 90 degrees and on views with different numbers of corners."""
    init_dets, distortion = dets, opt.distortion
    if DISTORTION_CHOICES[opt.distortion][0].wide:
        init_dets = virtual_pinhole_detections(dets, equidistant_focal([dets[k] for k in usable], target))
        distortion = "none"
    try:
        z = calibrate_zhang([init_dets[k] for k in usable], target, distortion, target.local_origin)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    used = [usable[k] for k in z.used]
    for k in usable:
        if k not in used:
            reports[k].used, reports[k].reason = False, "zhang: fewer than 6 measured corners"
    Ki = np.linalg.inv(z.K)
    sol = IacSolution(z.K, Ki.T @ Ki, float("nan"))
    D = None if distortion != opt.distortion else z.D
    return ClosedFormStart(sol, used, dict(zip(used, z.poses, strict=True)), init_dets, 0.0, [], D)


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
    except IndefiniteOmegaError as exc:
        raise CalibrationError(str(exc)) from None
    except DegenerateViewsError as exc:
        raise DegenerateStartError(str(exc)) from None
    for k_local, why in failed.items():
        rep = reports[usable[k_local]]
        rep.used, rep.reason = False, f"{opt.method}: {why}"
    return ClosedFormStart(sol, [usable[k] for k in used_local], grid_poses, init_dets, lam,
                           [sol.warning] if sol.warning else [])


# k1-equivalents kappa of the division models tried by :func:`division_start` (lambda = kappa / F^2,
# F the image's half diagonal): barrel to pincushion; the refinement is the judge among them
RESTART_KAPPAS = (-0.1, -0.2, -0.3, -0.4, -0.5, -0.6, -0.8, 0.1, 0.2)


def division_start(dets: list[Detection], usable: list[int], target: Target, opt: CalibrationOptions,
                   reports: list[ViewReport], kappa: float) -> ClosedFormStart:
    """A closed-form start with the distortion taken out by a guessed division model, for circles
    without straight rows to find it from (a single ring through a strongly distorting lens).

    The edges are undistorted by p_u = c + (p - c) / (1 + lambda |p - c|^2) (Fitzgibbon 2001; c the
    image centre, lambda = kappa / F^2, F the half diagonal), the conics refitted and the circular
    points' closed form run on them (w = K^-T K^-1 from i'^T w i' = 0). A single ring's conics
    cannot tell lambda: a projective conic absorbs most of a radial distortion, so neither the
    edges' misfit to their conics nor the consistency of the circular points picks it (both were
    measured flat or biased on a k1 = -0.28 lens); but the refinement converges from a K within
    ~10 % of the truth with D = 0, and one of the kappas of :data:`RESTART_KAPPAS` gives one that
    close: the caller refines each and keeps the best fit. Where the full w is still not positive
    definite (small rings far from the centre), f alone is solved for with the principal point at
    the image centre (:func:`..geometry.iac.iac_focal_only`). D0 is plumb_bob's closest k1 (k2) to
    lambda (:func:`start_distortion`), the poses come from the undistorted conics. Raises
    :class:`CalibrationError` when w is degenerate or no f fits."""
    w, h = dets[0].width, dets[0].height
    lam = kappa / ((w * w + h * h) / 4.0)
    init = undistort_detections(dets, lam)
    try:
        sol, used_local, failed = intrinsics_closed_form([init[k] for k in usable], target, opt.method,
                                                         opt.zero_skew, focal_only=True)
    except DegenerateViewsError as exc:
        raise CalibrationError(str(exc)) from None
    for k_local, why in failed.items():
        rep = reports[usable[k_local]]
        rep.used, rep.reason = False, f"{opt.method}: {why}"
    return ClosedFormStart(sol, [usable[k] for k in used_local], {}, init, lam, [sol.warning] if sol.warning else [])


def start_poses(dets: list[Detection], start: ClosedFormStart, target: Target, opt: CalibrationOptions,
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
                drawn = lens.wide or start.division != 0.0  # the edges the closed form ran on
                pose = pose_from_view(start.init_dets[k] if drawn else dets[k], target, start.sol.K, origin)
        except (CircularPointError, np.linalg.LinAlgError) as exc:
            reports[k].used, reports[k].reason = False, f"pose: {exc}"
            continue
        views.append(observations(dets[k], target, origin, opt))
        poses0.append(pose_to_params(pose, dof))
        idx.append(k)
    return views, poses0, idx


def start_distortion(dets: list[Detection], start: ClosedFormStart, opt: CalibrationOptions, n: int, size: ImageSize
                     ) -> np.ndarray:
    """The start's own D, zero, or k1 (k2) of the plumb-line division model when grids were straightened."""
    w, h = size
    D0 = np.zeros(n)
    if start.D is not None:
        D0[: min(n, len(start.D))] = start.D[:n]
        return D0
    if start.division and "k1" in DISTORTION_MODELS[opt.distortion]:
        r_max = max(float(np.max(np.hypot(*(e.points - [w / 2, h / 2]).T))) for k in start.used for e in dets[k].edges)
        f = float(np.sqrt(start.sol.K[0, 0] * start.sol.K[1, 1]))
        D0[0], D0[1] = plumb_bob_from_division(start.division, f, r_max, "k2" in DISTORTION_MODELS[opt.distortion])
    return D0


# restarted fits whose costs over the same observations differ by at most this much chi-square (the
# data's own one-sigma likelihood interval) are tied: the data do not prefer either
RESTART_TIE_CHI2 = 1.0
RESTART_TIE_ROUND_PX = 0.01  # the tied fits' corner displacements are compared to this (not to the last bits)


def view_costs(res: RefineResult) -> np.ndarray:
    """Per view, the refinement's robust cost sum rho(r) (:meth:`.problem.Problem.robust_cost`) at
    its solution over *all* the observations it started with (``first_views``): those its outlier
    rejection dropped included, so that fits which rejected different observations are scored on
    the same data."""
    p = res.problem
    assert p is not None and res.x is not None and res.intr0 is not None
    full = Problem(res.first_views, p.dof, tuple(p.names[i] for i in p.free), p.use_offsets,
                   loss_scale=p.loss_scale, shape=tuple(SHAPE_NAMES[i] for i in p.shape_idx),
                   shape_frame=p.frame, lens=p.lens)
    f = full.residuals(res.x, res.intr0)
    return np.array([full.robust_cost(f[rows], p.loss_scale) for rows in full.rows_of_view])


def corner_displacement(res: RefineResult, size: ImageSize) -> float:
    """How far (px) the fitted distortion moves the image corners, where a session's views rarely
    reach and the model extrapolates: max over the four corners p of |K x_u(p) - p|, x_u(p) the
    pinhole coordinates (x/z, y/z) of the ray the fitted camera sees at p; inf where it has none
    (the model folds over before the corner)."""
    w, h = size
    cam = Camera(res.K, res.D, w, h, res.model)
    corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
    xu = cam.undistort_pixels(corners)
    d = np.linalg.norm(np.c_[xu, np.ones(4)] @ res.K[:2].T - corners, axis=1)
    return float(np.max(d)) if np.all(np.isfinite(d)) else float("inf")


def restart_order(fits: list[tuple[RefineResult, list[int]]], size: ImageSize) -> list[int]:
    """The order (indices into ``fits``: refinements with the session index of each of their
    views) in which restarted fits are tried, best first.

    Each fit is scored by its robust cost C over the observations of the views every fit posed,
    outliers included (:func:`view_costs`): the edge RMS after each fit's own outlier rejection is
    no score, since a fit that extrapolates badly towards the rim rejects the rim's edge points
    and so reaches a *lower* RMS on fewer points. Fits within the noise of the best,
    2 (C - C_best) / (kappa sigma^2) <= RESTART_TIE_CHI2 (sigma the best fit's RMS, kappa its
    residuals' correlation factor, :func:`.covariance.correlation_factors`; C ~ sum r^2 / 2), are
    tied: the data cannot tell them apart, only their extrapolation to the unobserved image
    corners differs, and that decides among them, the smallest :func:`corner_displacement` (to
    RESTART_TIE_ROUND_PX) first: a weak prior of no distortion where nothing was observed, as
    mrcal's regularisation of the lens parameters pulls them towards zero where the data leave
    them free. The rest follow by cost; equal keys keep the fits' order."""
    if not fits:
        return []
    common = set.intersection(*(set(idx) for _, idx in fits))
    cost = [float(sum(c for k, c in zip(idx, view_costs(res), strict=True) if k in common)) for res, idx in fits]
    best = int(np.argmin(cost))
    res = fits[best][0]
    tol = 0.5 * RESTART_TIE_CHI2 * max(res.kappa) * res.rms**2
    tied = [i for i in range(len(fits)) if cost[i] - cost[best] <= tol]
    shift = {i: float(np.round(corner_displacement(fits[i][0], size) / RESTART_TIE_ROUND_PX)) for i in tied}
    rest = [i for i in range(len(fits)) if i not in shift]
    return sorted(tied, key=lambda i: shift[i]) + sorted(rest, key=lambda i: cost[i])
