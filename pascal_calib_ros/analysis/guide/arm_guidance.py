"""Guidance for a robot arm: candidate tool poses near the visited ones, ranked by the predicted
projection uncertainty and the predicted uncertainty of the hand-eye transform, both from the
first suggestion on (the issue asked for the hand-eye terms "once the intrinsics are on their
way"; in the arm study, 20 seeds, joining them from the start lowered X's rotation error by half
at 6 views, 27 % at 8 and 12 % at 12, and the projection error at 6 views fourfold:
docs/guided-sessions.md).

**Frames** (:mod:`..calibrate.handeye`): per view the tool pose G (T_base_tool), the hand-eye
transform X and the target's pose Y close the loop; with C = camera_T_target (target YAML frame)
eye in hand G = Y C^-1 X^-1 (X = T_tool_camera, Y = T_base_target), eye to hand G = X C Y^-1
(X = T_base_camera, Y = T_tool_target).

**Candidates.** Views of the target placed as for a person (:mod:`.candidates`), also turned
about the optical axis (what a wrist does best, and what the hand-eye rotation needs: the
motions' rotation axes spread, as Tsai and Lenz ask: "A new technique for fully autonomous and
efficient 3D robotics hand/eye calibration", IEEE TRA 5(3), 1989), mapped to tool poses. A view
turned :data:`DISTINCT_ROLL_DEG` or more from a visited one counts as new: for a person it is the
same view, for the arm a new motion. The latest visited views are also turned wide (rolled 135-180
degrees, their tilt mirrored across the line of sight: :class:`ArmRanking`), which spreads the tool
orientations at the views' own distance. The package knows no kinematics: a tool pose is kept if it
lies within ``reach`` metres of a visited one and within ``max_turn`` degrees of the nearest
visited orientation (a trust region).

**Prediction.** The joint problem of :class:`..calibrate.handeye.chain.ChainProblem` (intrinsics free,
X, Y, every view's pose; the chain rows weighted by the arm's estimated accuracy), linearised at
the hand-eye estimate with the views synthesised at their estimated poses (a symmetric grid's
labelling does not matter then); a candidate adds its image rows and its six chain rows
(:class:`.guidance.ChainRows`). The readout adds X's six parameters: sigma of its rotation (deg)
and translation (mm), norms over the axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ...calibrate import CalibrationOptions
from ...calibrate.handeye import ChainProblem, HandEyeResult, RobotChain, chain_pose
from ...geometry import DISTORTION_CHOICES, ImageSize, Transform, left_jacobian
from ...modes import HandEyeMode
from ...targets import Target
from .candidates import (
    Candidate,
    CandidateGrid,
    Feasibility,
    Placement,
    candidate_placements,
    default_feasibility,
    feasibility_problems_of,
    partial_placements,
    place_arrays,
    placement_of,
    transforms,
    with_ray,
)
from .detector_bias import BiasedPredictor, DetectorBias
from .guidance import ChainRows, Linearisation, NoiseModel, Prediction, ViewPredictor, semi_minor_px
from .view_ranking import RankedView, distinct_from_all, rank_candidates
from .view_synthesis import synthesise_views


@dataclass(frozen=True)
class ArmFrames:
    """The hand-eye loop's fixed transforms (module docstring)."""

    mode: HandEyeMode
    X: Transform
    Y: Transform  # target YAML frame -> base (eye in hand) or -> tool (eye to hand)

    def tool_pose(self, camera_T_target: Transform) -> Transform:
        """T_base_tool that puts the target at ``camera_T_target``."""
        C = camera_T_target
        if self.mode == "eye_in_hand":
            return self.Y @ C.inverse() @ self.X.inverse()
        return self.X @ C @ self.Y.inverse()

    def tool_poses(self, RC: np.ndarray, tC: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`tool_pose` of many camera_T_target poses (rotation matrices (N, 3, 3), translations
        (N, 3)) at once, as rotation matrices and translations."""
        RX, tX, RY, tY = self.X.R, self.X.translation, self.Y.R, self.Y.translation
        if self.mode == "eye_in_hand":  # Y C^-1 X^-1
            R1 = np.einsum("ij,nkj->nik", RY, RC)  # RY RC^T
            R = np.einsum("nij,kj->nik", R1, RX)  # ... RX^T
            return R, tY - np.einsum("nij,nj->ni", R1, tC) - np.einsum("nij,j->ni", R, tX)
        R1 = np.einsum("ij,njk->nik", RX, RC)  # X C Y^-1
        R = np.einsum("nij,kj->nik", R1, RY)
        return R, tX + np.einsum("ij,nj->ni", RX, tC) - np.einsum("nij,j->ni", R, tY)

    def camera_pose(self, tool: Transform) -> Transform:
        """camera_T_target of the tool pose ``tool`` (T_base_tool)."""
        if self.mode == "eye_in_hand":
            return self.X.inverse() @ tool.inverse() @ self.Y
        return self.X.inverse() @ tool @ self.Y


@dataclass(frozen=True)
class TrustRegion:
    """Tool poses within ``reach`` m of a visited position and ``max_turn`` deg of the nearest
    visited orientation."""

    visited: tuple[Transform, ...]
    reach: float = 0.3
    max_turn: float = 120.0

    def problems(self, tools: Sequence[Transform]) -> list[str]:
        """Per tool pose why it is outside ("" if inside)."""
        if not tools:
            return []
        return self.problems_of(np.stack([t.R for t in tools]), np.array([t.translation for t in tools]))

    def problems_of(self, R: np.ndarray, t: np.ndarray) -> list[str]:
        """:meth:`problems` of tool poses given as rotation matrices (N, 3, 3) and translations (N, 3)."""
        if not len(t):
            return []
        vt = np.array([v.translation for v in self.visited])
        dist = np.min(np.linalg.norm(t[:, None, :] - vt[None, :, :], axis=2), axis=1)
        vq = Rotation.concatenate([v.rotation for v in self.visited]).as_quat()
        tq = Rotation.from_matrix(R).as_quat()
        turn = np.degrees(2 * np.arccos(np.clip(np.max(np.abs(np.einsum("nk,mk->nm", tq, vq)), axis=1), -1.0, 1.0)))
        out = []
        for d, a in zip(dist, turn, strict=True):
            if d > self.reach:
                out.append(f"{d:.2f} m from the nearest visited tool position (reach {self.reach:g} m)")
            elif a > self.max_turn:
                out.append(f"turned {a:.0f} deg from the nearest visited orientation (max turn {self.max_turn:g})")
            else:
                out.append("")
        return out


@dataclass(frozen=True)
class ArmModel:
    """The linearised joint problem of an arm session and what reads X out of it."""

    predictor: ViewPredictor
    frames: ArmFrames
    problem: ChainProblem
    kappa: float = 1.0  # the edge rows' correlation factor the image rows' variances were divided by


def _local_y(target: Target, Y_yaml: Transform) -> Transform:
    """Y of the refinement's local frame (origin at the first circle's centre)."""
    o = np.array(target.local_origin)
    return Y_yaml @ Transform.from_rt(np.eye(3), np.r_[o, 0.0])


def arm_model(hres: HandEyeResult, robot_poses: Sequence[Transform], target: Target, noise: NoiseModel,
              size: ImageSize,
              options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
              bias: DetectorBias | None = None, keep_kappa: bool = True) -> ArmModel:
    """The joint problem at the hand-eye estimate (module docstring). ``robot_poses`` are the tool
    poses of the views the hand-eye calibration used, in their order; ``noise`` the image rows'
    noise model (from the intrinsic calibration: the correlation factor kappa included). With
    ``bias`` every view's pose carries the detector's bias (:mod:`.detector_bias`); without
    ``keep_kappa`` the image rows' variances are divided by the refinement's kappa (what reaches X;
    the ranking's projection term puts it back, :func:`suggest_arm_views`). Both were tried for
    issue 36 and are off by default: in the arm study they did not lower X's errors
    (docs/guided-sessions.md)."""
    cal = hres.calibration
    if len(robot_poses) != len(cal.poses):
        raise ValueError(f"{len(robot_poses)} robot poses for {len(cal.poses)} views used")
    lens, free_d = DISTORTION_CHOICES[cal.distortion_model]
    free = ("fx", "fy", "cx", "cy") + (() if options.zero_skew else ("skew",)) + free_d
    cam = cal.camera()
    P = np.asarray(cal.poses, float).reshape(-1, 6)
    synth = synthesise_views(target, cam, Rotation.from_rotvec(P[:, :3]).as_matrix(), P[:, 3:6], options)
    views, weights = [sv.data for sv in synth], [sv.weight for sv in synth]
    M = [chain_pose(g, hres.mode) for g in robot_poses]
    chain = RobotChain(M, hres.mode == "eye_in_hand", np.radians(max(hres.robot_error_deg, 1e-4)),
                       max(hres.robot_error_mm, 1e-3) / 1000, 1.0)
    prob = ChainProblem(views, free, options.edge_offsets, chain, lens=lens)
    D = np.asarray(cal.D, float).reshape(-1)
    intr0 = np.array([cal.K[0, 0], cal.K[1, 1], cal.K[0, 2], cal.K[1, 2], cal.K[0, 1], *D])
    Yl = _local_y(target, hres.target)
    xy = np.r_[hres.hand_eye.rotvec, hres.hand_eye.translation, Yl.rotvec, Yl.translation]
    x = prob.pack_chain(intr0, [np.asarray(p, float) for p in cal.poses], np.zeros(len(views)), xy)
    # the image rows' variances from the noise model; the chain rows in px per sigma of the same scale
    var_img = np.concatenate([np.full(len(v.points), noise.edge_variance(semi_minor_px(v))) for v in views]
                             + [np.full(2 * len(v.corners), noise.corner) for v in views])  # edges, then corners
    ref = cal.refinement
    kappa = ref.kappa if not keep_kappa and ref is not None else (1.0, 1.0)
    var_img[:prob.n_edge] /= max(kappa[0], 1e-6)
    var_img[prob.n_edge:] /= max(kappa[1], 1e-6)
    chain.scale = float(np.sqrt(max(np.median(var_img), 1e-12)))
    n_img = prob.n_edge + 2 * prob.n_corner
    var = np.r_[var_img, np.full(6 * prob.nv, chain.scale**2)]
    w = np.r_[np.concatenate([wt[:len(v.points)] for v, wt in zip(views, weights, strict=True)]),
              np.concatenate([wt[len(v.points):] for v, wt in zip(views, weights, strict=True)]),
              np.ones(6 * prob.nv)]
    assert len(w) == n_img + 6 * prob.nv
    extra = np.zeros((6, len(x)))
    extra[:, prob.n_base:prob.n_base + 6] = np.eye(6)
    lin = Linearisation(prob, x, intr0, var, w, cal.model, extra)
    pred = ViewPredictor(lin, size) if bias is None else BiasedPredictor(lin, size, n_img, bias)
    return ArmModel(pred, ArmFrames(hres.mode, hres.hand_eye, hres.target), prob, float(kappa[0]))


def hand_eye_sigmas(model: ArmModel, cov: np.ndarray) -> tuple[float, float]:
    """(rotation sigma deg, translation sigma mm) of X from a readout covariance (norms over the
    axes; the rotation as small rotations about the parent frame's axes)."""
    k0 = cov.shape[-1] - 6
    rv = model.problem.chain_params(model.predictor.lin.x)[:3]
    J = left_jacobian(rv)  # d (small rotation about the parent axes) / d rvec
    cr = J @ cov[..., k0:k0 + 3, k0:k0 + 3] @ J.T
    ct = cov[..., k0 + 3:k0 + 6, k0 + 3:k0 + 6]
    deg = np.degrees(np.sqrt(np.maximum(np.trace(cr, axis1=-2, axis2=-1), 0.0)))
    mm = 1000 * np.sqrt(np.maximum(np.trace(ct, axis1=-2, axis2=-1), 0.0))
    return deg, mm


def chain_rows(model: ArmModel, tools: Sequence[Transform]) -> ChainRows:
    """The six chain rows of candidate views taken at the tool poses ``tools`` (their Jacobian over
    the globals and over each candidate's own pose, by central differences)."""
    prob = model.problem
    x = model.predictor.lin.x
    xy = prob.chain_params(x)
    M = [chain_pose(g, model.frames.mode) for g in tools]
    ng, pv, b = prob.ng, prob.per_view, prob.n_base

    def rows(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        P = np.asarray(poses, float).reshape(len(M), -1)[:, :6]
        h, n = 1e-6, prob.N_CHAIN
        # every perturbation in one batch: the 12 globals up and down, then the 6 pose parameters
        E, Ep = h * np.eye(n), h * np.eye(6)[:, None, :]
        xys = np.concatenate([xy + E, xy - E, np.tile(xy, (12, 1))])
        ps = np.concatenate([np.broadcast_to(P, (2 * n, len(M), 6)), P + Ep, P - Ep])
        r = prob.chain_residuals(xys, ps, M)  # (36, candidates, 6)
        Jg = np.zeros((len(M), 6, ng))
        Jg[:, :, b:b + n] = ((r[:n] - r[n:2 * n]) / (2 * h)).transpose(1, 2, 0)
        Jv = np.zeros((len(M), 6, pv))
        Jv[:, :, :6] = ((r[2 * n:2 * n + 6] - r[2 * n + 6:]) / (2 * h)).transpose(1, 2, 0)
        return Jg, Jv

    return ChainRows(rows, float(prob.chain.scale**2))


DISTINCT_ROLL_DEG = 20.0  # an arm's view rolled this far from another is a new motion (view_ranking.distinct)
# tilted 25, 35 and 45 degrees: with 25 and 45 only, the guide took mostly 25 degree views (mean 26 against
# the designed set's 32) and 12 guided views gave X 1.21x / 1.25x (rotation / translation) the error of
# 20 designed ones; with 35 as well 1.07x / 0.97x, fx and the projection error below the designed 20's
# (arm study, 20 seeds x 4 noise draws: docs/guided-sessions.md). Rolls of -60, 0 and 60 degrees (the
# local candidates turn a visited view by 25-90 degrees more): rolls every 60 degrees gave X's translation
# sigma 0.089 mm against 0.101 mm in the guide's model at the truth (12 views), but not in the study's
# true errors (1.12 / 1.41 and, with goals weighted toward the translation, 1.30 / 1.21), at twice the
# candidates
ARM_GRID = CandidateGrid(cols=4, rows=3, span=0.7, sizes=(0.35, 0.5), tilts_deg=(25.0, 35.0, 45.0), axes=6,
                         rolls_deg=(-60.0, 0.0, 60.0))
LOCAL_VIEWS = 10  # the latest visited views around which local candidates are made
# the latest visited views also turned wide (local_placements): in the arm study (10 seeds x 3 redraws, 12 guided
# views against 20 designed) X's rotation / translation went from 1.12x / 0.94x to 1.06x / 0.95x (worst seed
# 2.19x to 1.69x) and, in an arm-dominated cell, from 1.14x / 1.29x to 1.13x / 1.18x; wide turns of all 10 local
# views gave 1.06x / 0.96x and 1.11x / 1.11x at a third more candidates (docs/guided-sessions.md, third study)
WIDE_VIEWS = 4


@dataclass(frozen=True)
class ArmGoals:
    """What an arm session is done at: the worst projection sigma over the image (px) and the
    sigma of X's rotation (deg) and translation (mm), norms over the axes."""

    sigma_px: float = 0.1
    rotation_deg: float = 0.01
    translation_mm: float = 0.1


@dataclass(frozen=True)
class ArmRanking:
    """Options of the arm's ranking beyond the goals (issue 36). The default turns the latest
    :data:`WIDE_VIEWS` visited views wide; the spread term is off.

    ``spread_weight``: adds ``spread_weight * F * ((s_deg / goal_deg)^2 + (s_mm / goal_mm)^2)`` to a
    candidate's score, s the arm's estimated sigma per axis and pose and F = trace((N (I - R_m^T
    R_m))^-1) over the visited tool orientations and the candidate's (:func:`orientation_spread`):
    the arm-only figure of X, which the image rows' share (kappa-inflated) hides in the joint
    prediction. ``wide_turns``: local candidates also rolled by +-135 and 180 degrees and their tilt
    axis turned by +-120 and 180 (Tsai and Lenz: the motions' rotation axes spread, large angles), of
    the latest ``wide_views`` visited views."""

    spread_weight: float = 0.0
    wide_turns: bool = True
    wide_views: int = WIDE_VIEWS


def orientation_spread(visited: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """F = trace(I_R^-1) per candidate, I_R = N (I - R_m^T R_m), R_m the mean of the N rotation
    matrices ``visited`` (V, 3, 3) and the candidate's (M, 3, 3).

    The chain's rotation rows alone (the arm's noise delta_i ~ N(0, s^2 I) in the tool frame, X
    and Y free): per view x = R_i^T z - delta_i, z Y's rotation in the base frame; eliminating z
    leaves the information sum_i I - (sum_i R_i)^T (sum_i R_i) / N = N (I - R_m^T R_m) on X's
    rotation, over s^2 (first-order least squares, e.g. Hartley & Zisserman, Multiple View
    Geometry, 2nd ed., A5.2); the translation rows give the same matrix over the arm's position
    variance. So s sqrt(F) is X's sigma (norm over the axes) from the arm's noise alone: no less than
    sqrt(3 / N) s, reached when the tool orientations average to zero (Tsai and Lenz's widely
    spread rotation axes)."""
    n = len(visited) + 1
    Rm = (visited.sum(axis=0)[None] + candidates) / n
    info = n * (np.eye(3)[None] - np.einsum("mji,mjk->mik", Rm, Rm)) + 1e-9 * np.eye(3)[None]
    return np.trace(np.linalg.inv(info), axis1=-2, axis2=-1)


@dataclass(frozen=True)
class ArmSuggestion:
    """A suggested view with the tool pose that takes it and the predicted sigmas."""

    view: RankedView
    tool: Transform  # T_base_tool
    predicted_rotation_deg: float
    predicted_translation_mm: float


@dataclass(frozen=True)
class ArmSuggestions:
    sigma_px: float  # projection sigma over the image now (the joint problem's)
    rotation_deg: float  # sigma of X now
    translation_mm: float
    suggestions: list[ArmSuggestion]
    n_candidates: int  # feasible views inside the trust region


def local_placements(model: ArmModel, target: Target, trust: TrustRegion, wide: int = 0) -> list[Placement]:
    """Placements near those of the latest visited views (a tight trust region may admit nothing
    of the coarse grid), each far enough to be a new view (:func:`.view_ranking.distinct`): turned
    about the optical axis by +-25, +-45 and 90 degrees, tilted 20 degrees more or less, its tilt
    axis turned by +-60 degrees, moved by a quarter of the image, 25 % nearer or 30 % farther;
    the latest ``wide`` of them (:class:`ArmRanking`) also turned by +-135 and 180 degrees and their
    tilt axis by +-120 and 180 (rolled 0 and +-60 degrees)."""
    cam = model.predictor.camera_sized
    out = []
    latest = trust.visited[-LOCAL_VIEWS:]
    for k, g in enumerate(latest):
        p = placement_of(target, cam, model.frames.camera_pose(g))
        u, v = p.pixel
        du, dv = 0.25 * cam.width, 0.25 * cam.height
        out += [replace(p, roll_deg=p.roll_deg + r) for r in (-90.0, -45.0, -25.0, 25.0, 45.0, 90.0)]
        out += [replace(p, tilt_deg=max(p.tilt_deg + d, 0.0)) for d in (-20.0, 20.0)]
        out += [replace(p, axis_deg=p.axis_deg + d, roll_deg=p.roll_deg + r) for d in (-60.0, 60.0) for r in (-25, 25)]
        out += [replace(p, pixel=(u + a, v + b)) for a, b in ((du, 0.0), (-du, 0.0), (0.0, dv), (0.0, -dv))]
        out += [replace(p, distance=p.distance * f) for f in (0.75, 1.3)]
        if k >= len(latest) - wide:
            out += [replace(p, roll_deg=p.roll_deg + r) for r in (-135.0, 135.0, 180.0)]
            out += [replace(p, axis_deg=p.axis_deg + d, roll_deg=p.roll_deg + r) for d in (-120.0, 120.0, 180.0)
                    for r in (-60.0, 0.0, 60.0)]
    return out


def arm_candidates(model: ArmModel, target: Target, trust: TrustRegion, grid: CandidateGrid = ARM_GRID,
                   rules: Feasibility | None = None, wide: int = 0) -> tuple[list[Candidate], list[Transform]]:
    """Feasible views whose tool pose lies in the trust region, and those tool poses: the grid's
    placements and placements near the visited views (:func:`local_placements`, ``wide`` passed on:
    the latest visited views that get wide turns)."""
    cam = model.predictor.camera_sized
    rules = rules or default_feasibility(target, cam.width)
    placements = candidate_placements(cam, grid, target) + partial_placements(cam, target) \
        + local_placements(model, target, trust, wide)
    ok = with_ray(cam, placements)
    R, t = place_arrays(target, cam, ok)
    # the trust region first (one batch of tool poses), then the feasibility rules on what is left
    GR, Gt = model.frames.tool_poses(R, t)
    inside = np.array([k for k, why in enumerate(trust.problems_of(GR, Gt)) if not why], int)
    feasible = feasibility_problems_of(target, cam, R[inside], t[inside], rules)
    keep = inside[[j for j, why in enumerate(feasible) if not why]]
    seen = [placement_of(target, cam, model.frames.camera_pose(g)) for g in trust.visited]
    placed = [ok[k] for k in keep]
    if seen and len(keep):
        new = distinct_from_all(placed, seen, cam.size, roll_deg=DISTINCT_ROLL_DEG)
        keep, placed = keep[new], [p for p, n in zip(placed, new, strict=True) if n]
    return ([Candidate(p, T) for p, T in zip(placed, transforms(R[keep], t[keep]), strict=True)],
            transforms(GR[keep], Gt[keep]))


def suggest_arm_views(model: ArmModel, target: Target, trust: TrustRegion, n: int = 5,
                      goals: ArmGoals = ArmGoals(), grid: CandidateGrid = ARM_GRID,
                      options: CalibrationOptions = CalibrationOptions(),  # noqa: B008
                      ranking: ArmRanking = ArmRanking()) -> ArmSuggestions:
    """The ``n`` best tool poses (module docstring): ranked by kappa (sigma_px / goal)^2 +
    (sigma_rot / goal)^2 + (sigma_trans / goal)^2 of X, from the first suggestion on (kappa the
    factor :func:`arm_model` took out of the image rows: the intrinsics' variances scale with it),
    plus the orientation-spread term of ``ranking`` (:class:`ArmRanking`, off by default)."""
    pred = model.predictor
    now = pred.sigma_now()
    deg_now, mm_now = hand_eye_sigmas(model, pred.cov_now)
    cands, tools = arm_candidates(model, target, trust, grid, wide=ranking.wide_views if ranking.wide_turns else 0)
    chain = model.problem.chain
    arm_share = ((np.degrees(chain.sigma_rot) / goals.rotation_deg) ** 2
                 + (1000 * chain.sigma_trans / goals.translation_mm) ** 2)
    visited_R = np.stack([g.R for g in trust.visited]) if trust.visited else np.zeros((0, 3, 3))

    def score(p: Prediction, idx: list[int]) -> np.ndarray:
        deg, mm = hand_eye_sigmas(model, p.readout_cov)
        s = (model.kappa * (p.sigma_px / goals.sigma_px) ** 2
             + (np.asarray(deg) / goals.rotation_deg) ** 2 + (np.asarray(mm) / goals.translation_mm) ** 2)
        if ranking.spread_weight > 0 and idx:
            F = orientation_spread(visited_R, np.stack([tools[i].R for i in idx]))
            s = s + ranking.spread_weight * arm_share * F
        return np.asarray(s)

    ranked = rank_candidates(pred, target, cands, n, options, score,
                             chain_of=lambda idx: chain_rows(model, [tools[i] for i in idx]),
                             roll_deg=DISTINCT_ROLL_DEG)
    by_pose = {id(c[1]): k for k, c in enumerate(cands)}
    out = []
    for r in ranked:
        deg, mm = hand_eye_sigmas(model, r.readout_cov)
        out.append(ArmSuggestion(r, tools[by_pose[id(r.pose)]], float(deg), float(mm)))
    return ArmSuggestions(now, float(deg_now), float(mm_now), out, len(cands))
