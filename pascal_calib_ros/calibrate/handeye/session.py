"""Hand-eye calibration: intrinsics, distortion, the camera-to-robot transform X and the target's
pose in one estimate from the circle edges (or checkerboard corners), with the robot chain as a
measurement.

Frames and the loop. Per view i the robot reports G_i = T_base_tool (the tool, or flange, in the
base frame). Eye in hand (camera on the tool): X = T_tool_camera, the target is fixed in the base
(Y = T_base_target). Eye to hand (camera fixed, the tool carries the target): X = T_base_camera,
Y = T_tool_target. With the chain pose M_i = G_i (eye in hand) or G_i^-1 (eye to hand) and the
view's target -> camera pose C_i, both modes are the loop Y = M_i X C_i (the convention of
OpenCV's calibrateHandEye and easy_handeye2: eye_in_hand gives camera -> gripper, eye_to_hand
camera -> base). X maps camera-frame points into its parent frame: it is what a
``static_transform_publisher`` with --frame-id parent --child-frame-id camera publishes.

Steps:

1. the intrinsic calibration of :func:`~.pipeline.calibrate` (its options, every lens model);
   each used view posed with that camera (circles: :func:`~.initial.pose_with_camera`;
   checkerboard only: PnP on the undistorted corners);
2. checks of the robot poses: at least 3 views with a pose, motions with two or more distinct
   rotation axes (pure translations or a single axis leave X undetermined);
3. symmetric targets: a grid that looks the same turned by 180 degrees may be labelled turned
   in some views; each view's labelling is chosen among the target's symmetries so that the
   motion pairs (A, B) agree in their screw invariants (rotation angle and the translation along
   the axis, which AX = XB preserves whatever X is), then again against the chain with X and Y
   from the closed form. A single ring (rotation about its axis invisible in any one view) is
   solved from its centre and normal per view, and the chain fixes each view's rotation about
   the axis;
4. closed form: Park & Martin, "Robot sensor calibration: solving AX = XB on the Euclidean
   group", IEEE Trans. Robotics and Automation 10(5), 1994: R_X = (M^T M)^-1/2 M^T with
   M = sum beta_k alpha_k^T (alpha, beta the rotation vectors of A_k, B_k), then t_X by linear
   least squares from (R_A - I) t_X = R_X t_B - t_A; over all view pairs. Views whose robot pose
   disagrees grossly with the images (a wrong frame, a pose from another view) are dropped with
   the reason (tested against X and Y from the other views);
5. the joint refinement (:class:`~.chain.ChainProblem`, :mod:`.chain_refinement`): X, Y, every view's camera pose and
   edge offset (and K, D only with ``HandEyeOptions.intrinsics="joint"``), with the edges' robust
   loss. By default ("hold") K and D are those of step 1 (the images alone) and held: a
   principal-point error acts like a constant camera rotation delta_c / f that X absorbs, and the
   arm's errors, fitted through the chain, drag the principal point (and with it X's rotation)
   further off than the images put it; the chain is a measurement of each camera pose
   with the arm's accuracy as its standard deviation (not a constraint: real arms are off by
   tenths of a millimetre, and deriving every camera pose from the robot pose makes the estimate
   follow the arm's errors). The arm's accuracy is estimated from the data (variance components:
   sigma^2 <- sum r^2 / redundancy of the chain rows, iterated) unless told otherwise. Neighbouring
   edge points (and checkerboard corners) err together: the edges weigh 1 / kappa against the
   chain, kappa from the residuals' autocorrelation (:func:`~..covariance.correlation_factor`), and their
   covariance is inflated by kappa;
6. the sigmas of X and Y: the larger per axis of the covariance of step 5 and a delete-a-group
   jackknife over the views (:func:`~.chain_refinement.jackknife_spread`; it sees view-to-view detection biases and the
   arm's systematic errors that the residuals' covariance does not); with the intrinsics held,
   their share added: the images-only covariance of K, D carried through dx / dtheta =
   -A_xx^-1 A_xtheta (A the normal matrix of the refinement with the intrinsics free); and the
   share of the arm's systematic position error, which no session measures, from a stated prior
   (``HandEyeOptions.arm_accuracy_mm`` / ``arm_accuracy_length``, :func:`~.sigma.arm_field_share`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from ...detect import Detection, DetectionRefusal
from ...geometry import Transform
from ...modes import HandEyeMode
from ...targets import Target
from ..intrinsic.options import CalibrationOptions
from ..intrinsic.pipeline import DEFAULT_OPTIONS
from ..intrinsic.result import CalibrationError, CalibrationResult, ViewReport
from ..intrinsic.warm import calibrate_warm
from ..solver.observations import ViewData
from .chain_refinement import ChainSolution, ChainStart, jackknife_spread, refine_chain
from .closed_form import (
    Motions,
    chain_disagreement,
    chain_pose,
    check_robot_poses,
    complete_ring_poses,
    hand_eye_closed_form,
    motion_pairs,
    park_martin_motions,
    ring_closed_form,
    target_from_chain,
)
from .labelling import label_consistently, target_symmetries
from .options import MIN_VIEWS, HandEyeError, HandEyeOptions, HandEyeResult, HandEyeView
from .outliers import Disagreement, drop_disagreeing_views
from .sigma import Spread
from .view_poses import posed_views, refined_poses
from .warm import HandEyeStart


def _checked(dets: list[Detection], robot_poses: Sequence[Transform | None], text: HandEyeMode | str,
             he: HandEyeOptions | None) -> tuple[HandEyeOptions, list[Detection]]:
    """The options for ``mode`` and the detections with views without a robot pose refused; a
    HandEyeError for inputs that cannot work."""
    try:
        mode = HandEyeMode(text)
    except ValueError:
        raise HandEyeError(f"unknown hand-eye mode {text!r}; choose one of {', '.join(HandEyeMode)}") from None
    he = replace(he, mode=mode) if he is not None else HandEyeOptions(mode)
    if len(robot_poses) != len(dets):
        raise HandEyeError(f"{len(robot_poses)} robot poses for {len(dets)} views: one per view (None if unknown)")
    for k, p in enumerate(robot_poses):
        if p is not None and not isinstance(p, Transform):
            raise HandEyeError(f"robot pose {k} is a {type(p).__name__}, not a Transform")
    if he.robot_sigma_mm <= 0 or he.robot_sigma_deg <= 0:
        raise HandEyeError("the robot's pose sigmas must be positive")
    if he.arm_accuracy_problem():
        raise HandEyeError(he.arm_accuracy_problem())
    dets = [d if p is not None or not d.ok else replace(d, reason="no robot pose for this view",
                                                           refusal=DetectionRefusal.NO_ROBOT_POSE)
            for d, p in zip(dets, robot_poses, strict=True)]
    check_robot_poses([p for d, p in zip(dets, robot_poses, strict=True) if d.ok and p is not None], mode)
    return he, dets


def _closed_form_solver(M: list[Transform], C: list[Transform], axisymmetric: bool
                        ) -> Callable[[list[int]], tuple[Transform, Transform, list[Transform]]]:
    """X, Y and the views' poses from a subset of the views: Park-Martin, or the ring's linear form
    (each view's rotation about the ring's axis then fixed by the chain). Park-Martin's motion
    pairs are formed once for all views; an ascending subset takes the pairs within it (in the
    same order: the same X as :func:`hand_eye_closed_form` of the subset)."""
    pairs = motion_pairs(M, C) if not axisymmetric and len(M) > 1 else None
    i, j = np.triu_indices(len(M), 1)

    def solve(sel: list[int]) -> tuple[Transform, Transform, list[Transform]]:
        Ms, Cs = [M[k] for k in sel], [C[k] for k in sel]
        if axisymmetric:
            X, Y = ring_closed_form(Ms, np.array([c.translation for c in Cs]), np.array([c.R[:, 2] for c in Cs]))
            return X, Y, complete_ring_poses(Ms, X, Y, Cs)
        if pairs is None or list(sel) != sorted(set(sel)):
            X, Y = hand_eye_closed_form(Ms, Cs)
            return X, Y, Cs
        inside = np.zeros(len(M), bool)
        inside[sel] = True
        keep = inside[i] & inside[j]
        X = park_martin_motions(Motions(*(a[keep] for a in (pairs.alpha, pairs.beta, pairs.RA, pairs.tA, pairs.tB))))
        return X, target_from_chain(Ms, X, Cs), Cs

    return solve


def calibrate_hand_eye(dets: list[Detection], robot_poses: Sequence[Transform | None], target: Target,
                       mode: HandEyeMode | str,
                       options: CalibrationOptions = DEFAULT_OPTIONS, he: HandEyeOptions | None = None
                       ) -> HandEyeResult:
    """Joint intrinsic + hand-eye calibration (module docstring). ``robot_poses[i]`` is the tool
    pose in the base frame (T_base_tool) at view i, None if unknown (the view is refused)."""
    return calibrate_hand_eye_warm(dets, robot_poses, target, mode, options, he)[0]


def calibrate_hand_eye_warm(dets: list[Detection], robot_poses: Sequence[Transform | None], target: Target,
                            mode: HandEyeMode | str,
                            options: CalibrationOptions = DEFAULT_OPTIONS, he: HandEyeOptions | None = None,
                            start: HandEyeStart | None = None) -> tuple[HandEyeResult, HandEyeStart]:
    """:func:`calibrate_hand_eye`, warm from a previous call's ``start`` where it applies (:mod:`.warm`:
    the same estimate to the solves' tolerance), and the start of the next call."""
    given = tuple(dets), tuple(robot_poses)
    he, dets = _checked(dets, robot_poses, mode, he)
    if start is not None and not start.applies(*given, he):
        start = None
    try:
        cal, intrinsic = calibrate_warm(dets, target, options, start.intrinsic if start else None)
    except HandEyeError:
        raise
    except CalibrationError as e:
        raise HandEyeError(f"intrinsic calibration failed: {e}") from None
    reports = [replace(v) for v in cal.views]
    warnings = list(cal.warnings)
    axisymmetric = len({c.center for c in target.circles}) == 1 and not target.boards
    observed = dict(zip(intrinsic.first.idx, intrinsic.first.res.first_views, strict=True)) if intrinsic else None
    views, C, idx = posed_views(dets, reports, target, cal.camera(), options, axisymmetric, refined_poses(cal),
                                observed)
    M = [chain_pose(robot_poses[k], he.mode) for k in idx]  # type: ignore[arg-type]
    if len(idx) < MIN_VIEWS:
        raise HandEyeError(f"only {len(idx)} view(s) with a robot pose and a camera pose; need {MIN_VIEWS}")
    check_robot_poses([robot_poses[k] for k in idx], he.mode)  # type: ignore[misc]
    syms = [] if axisymmetric else target_symmetries(target, target.local_origin)
    if len(syms) > 1:  # symmetric targets: a consistent labelling through the robot chain
        C, views, more = label_consistently(M, C, views, syms, he.mode, target.name)
        warnings += more
    solve = _closed_form_solver(M, C, axisymmetric)
    active, dropped = drop_disagreeing_views(M, C, solve, he, axisymmetric)
    X0, Y0, C0 = solve(active)
    for i, d in dropped.items():
        reports[idx[i]].used, reports[idx[i]].reason = False, d.reason
    views, M, kept = [views[i] for i in active], [M[i] for i in active], [idx[i] for i in active]
    warm = start.chain_start(kept, C0, [reports[k].edge_offset for k in kept], 6 + options.edge_offsets) \
        if start else None
    sol = refine_chain(views, ChainStart(X0, Y0, C0, M, cal), options, he, target, target.local_origin, warm)
    spread = sol.covariance
    if he.jackknife_groups >= 2 and len(views) >= 2 * he.jackknife_groups:
        # the jackknife holds the intrinsics when they are held ("hold"): their share is added after
        he_k = replace(he, robot_sigma_mm=sol.robot_error_mm, robot_sigma_deg=sol.robot_error_deg)
        solved = ChainStart(sol.X, sol.Y, sol.poses, M, replace(cal, K=sol.K, D=sol.D))
        spread = spread.maximum(jackknife_spread(views, solved, options, he_k, target, target.local_origin))
    spread = spread.root_sum_square(sol.intrinsics_share, sol.arm_share)
    if not sol.success:
        warnings.append("the joint refinement stopped early")
    if axisymmetric:
        warnings.append("a single ring: the target's rotation about its axis is not observable (reported "
                        "arbitrarily); X is not affected")
    per_view = _per_view(reports, kept, {idx[i]: d for i, d in dropped.items()},
                         chain_disagreement(M, sol.X, sol.Y, sol.poses, he.mode))
    for j, k in enumerate(kept):
        reports[k].used, reports[k].reason = True, ""
        reports[k].rms, reports[k].edge_offset = float(sol.view_rms[j]), float(sol.offsets[j])
    result = _result(cal, sol, views, reports, warnings=warnings, he=he, per_view=per_view, X0=X0, spread=spread,
                     target=target)
    return result, HandEyeStart(*given, he, intrinsic, tuple(kept), tuple(C0), sol.passes[0])


def _per_view(reports: list[ViewReport], kept: list[int], dropped: dict[int, Disagreement],
              disagreement: tuple[np.ndarray, np.ndarray]) -> list[HandEyeView]:
    """Per view of the session: name, used, reason, and its chain's disagreement (mm, deg)."""
    mm, deg = disagreement
    pos = {k: j for j, k in enumerate(kept)}
    out = []
    for k, rep in enumerate(reports):
        if k in pos:
            out.append(HandEyeView(rep.name, True, "", float(mm[pos[k]]), float(deg[pos[k]])))
        else:
            d = dropped.get(k)
            out.append(HandEyeView(rep.name, False, rep.reason or "not used", d.mm if d else float("nan"),
                                   d.deg if d else float("nan")))
    return out


def _result(cal: CalibrationResult, sol: ChainSolution, views: list[ViewData], reports: list[ViewReport],
            warnings: list[str], he: HandEyeOptions, per_view: list[HandEyeView], X0: Transform, spread: Spread,
            target: Target) -> HandEyeResult:
    """The hand-eye result: the camera of the joint estimate (its views' residuals), X and Y (the
    target's pose in its YAML frame) with their sigmas."""
    origin = target.local_origin
    to_yaml = Transform.from_rt(np.eye(3), [-origin[0], -origin[1], 0.0])  # YAML frame -> local frame
    calib = replace(cal, K=sol.K, D=sol.D, rms=sol.rms, std=sol.std, views=reports, warnings=warnings,
                    poses=[np.r_[c.rotvec, c.translation] for c in sol.poses],
                    edge_points=[v.points for v in views], edge_residuals=sol.edge_residuals,
                    edge_circles=[v.circle_ids for v in views], corner_points=[v.corners for v in views],
                    corner_residuals=sol.corner_residuals)
    return HandEyeResult(
        calibration=calib, mode=he.mode, hand_eye=sol.X, translation_std_mm=spread.x_mm,
        rotation_std_deg=spread.x_deg, target=sol.Y @ to_yaml, views_used=len(views), rms_px=sol.rms,
        robot_error_mm=sol.robot_error_mm, robot_error_deg=sol.robot_error_deg, per_view=per_view,
        warnings=warnings, closed_form=X0, target_std_mm=spread.y_mm, target_std_deg=spread.y_deg,
        start_K=cal.K.copy(), arm_share_mm=sol.arm_share.x_mm, arm_share_deg=sol.arm_share.x_deg,
        arm_accuracy_mm=he.arm_accuracy_mm, arm_accuracy_length=he.arm_accuracy_length,
        intrinsics_share_mm=sol.intrinsics_share.x_mm, intrinsics_share_deg=sol.intrinsics_share.x_deg)
