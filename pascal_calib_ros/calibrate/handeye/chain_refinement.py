"""The joint refinement of X, Y and every view's camera pose with the robot chain as a measurement
(:class:`~.chain.ChainProblem`), the arm's sigmas by variance components, and the covariance of X
and Y with the held intrinsics' share.

The normal matrix weighs the edges as independent points of variance s_edge^2 and the chain in
units of ``chain.scale`` = s_edge sqrt(kappa): the covariance is its inverse times kappa s_edge^2
(edges of variance kappa s_edge^2, the chain of its sigmas). With the intrinsics held ("hold"),
their error moves X and Y by dx/dtheta = -A_rr^-1 A_rtheta (A of the joint problem with the
intrinsics free); their covariance is that of the images alone (the chain rows weighed zero).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...geometry import DISTORTION_CHOICES, LensModel, Transform
from ...modes import HandEyeMode
from ...targets import Target
from ..intrinsic.options import CalibrationOptions
from ..intrinsic.result import CalibrationResult
from ..solver.covariance import correlation_factor
from ..solver.lm import WARM_START, LMResult, levenberg_marquardt
from ..solver.observations import ViewData
from ..solver.problem import camera_from_intrinsics, shape_frame_of
from .chain import ChainProblem, RobotChain
from .options import HandEyeOptions
from .sigma import Spread, arm_field_share, spread_of

LOSS_SCALE = 0.3  # px: the edges' soft-L1 scale (as the intrinsic refinement's)


@dataclass(frozen=True)
class ChainStart:
    """Where the joint refinement starts: X, Y, each view's camera pose (target -> camera), the
    chain poses M_i and the camera of the intrinsic calibration."""

    X: Transform
    Y: Transform
    C: list[Transform]
    M: list[Transform]
    calibration: CalibrationResult


@dataclass
class ChainSolution:
    """The joint estimate: X, Y, each view's camera pose, the camera (K, D and its sigmas), the
    residuals' figures, the arm's error the data imply, and the per-axis sigmas of X and Y from the
    covariance, from the held intrinsics and from the arm's systematic error (prior)."""

    X: Transform
    Y: Transform
    poses: list[Transform]
    K: np.ndarray
    D: np.ndarray
    std: dict[str, float]
    rms: float
    offsets: np.ndarray
    view_rms: np.ndarray
    edge_residuals: list[np.ndarray]
    corner_residuals: list[np.ndarray]
    robot_error_mm: float
    robot_error_deg: float
    covariance: Spread
    intrinsics_share: Spread
    arm_share: Spread
    success: bool
    passes: list[np.ndarray] = field(default_factory=list)  # the solution of each variance-components pass


@dataclass
class _Setup:
    prob: ChainProblem
    chain: RobotChain
    x: np.ndarray
    intr0: np.ndarray
    free: tuple[str, ...]
    shape: tuple[str, ...]
    frame: tuple[float, float, float, float] | None
    lens: LensModel


def _setup(views: list[ViewData], start: ChainStart, opt: CalibrationOptions, he: HandEyeOptions, target: Target,
           origin: tuple[float, float]) -> _Setup:
    lens, free_d = DISTORTION_CHOICES[opt.distortion]
    free = ("fx", "fy", "cx", "cy") + (() if opt.zero_skew else ("skew",)) + free_d
    shape = tuple(opt.target_shape)
    frame = None
    if shape:
        pts = [np.array([c.center for c in target.circles]).reshape(-1, 2)]
        pts += [b.corner_points() for b in target.boards]
        frame = shape_frame_of(np.concatenate(pts) - np.array(origin))
    cal = start.calibration
    K0, D0 = cal.K, np.asarray(cal.D, float).reshape(-1)
    if len(D0) != lens.n:
        D0 = np.r_[D0, np.zeros(lens.n)][: lens.n]
    intr0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], 0.0 if opt.zero_skew else K0[0, 1], *D0])
    scale = max(float(cal.rms), 0.01) if np.isfinite(cal.rms) else 0.05
    chain = RobotChain(start.M, he.mode == HandEyeMode.EYE_IN_HAND, np.radians(he.robot_sigma_deg),
                       he.robot_sigma_mm / 1000, scale)
    prob = ChainProblem(views, () if he.intrinsics == "hold" else free, opt.edge_offsets, chain, LOSS_SCALE, shape,
                        frame, lens)
    xy = np.r_[start.X.rotvec, start.X.translation, start.Y.rotvec, start.Y.translation]
    x = prob.pack_chain(intr0, [np.r_[c.rotvec, c.translation] for c in start.C], np.zeros(len(views)), xy)
    return _Setup(prob, chain, x, intr0, free, shape, frame, lens)


def _variance_components(s: _Setup, views: list[ViewData], he: HandEyeOptions, warm: np.ndarray | None = None
                         ) -> tuple[LMResult, float, np.ndarray, list[np.ndarray]]:
    """Solve, re-estimating the arm's sigmas (sigma^2 <- sum r^2 / redundancy of the chain rows) and the
    chain's scale (the edges' s_edge sqrt(kappa)) until they settle; returns the solution, kappa, the
    pseudo-inverse of the solution's normal matrix and the solution of every pass. The redundancy of
    rows g is n_g - trace(A^+ J_g^T J_g) = n_g - sum((J_g A^+) * J_g), from their rows of the Jacobian
    alone. ``warm``: where the first pass starts (a previous call's first pass), every pass solved
    with :data:`~..lm.WARM_START`; the passes and their sigmas are the cold ones, each solve
    converging to the same point."""
    prob, chain, intr0 = s.prob, s.chain, s.intr0
    sig_r, sig_t = chain.sigma_rot, chain.sigma_trans
    rows_r, rows_t = prob.chain_rows()
    kappa, x = 1.0, s.x
    Ainv: np.ndarray | None = None
    passes: list[np.ndarray] = []
    for it in range(8 if he.estimate_robot_noise else 2):
        chain.sigma_rot, chain.sigma_trans = sig_r, sig_t
        if warm is not None:
            sol = levenberg_marquardt(prob, x if it else warm, intr0, LOSS_SCALE, max_iter=100, options=WARM_START)
        else:
            sol = levenberg_marquardt(prob, x, intr0, LOSS_SCALE, max_iter=100)
        x, Ainv = sol.x, None
        passes.append(x)
        # the edge scale (px) and the edges' correlation: what a chain residual of one sigma weighs
        n_rob = prob.n_robust
        s_edge = float(np.sqrt(np.sum(sol.weights[:n_rob] * sol.fun[:n_rob] ** 2) / max(n_rob - len(x), 1)))
        kappa_new = correlation_factor(prob, views, sol.fun)
        if not he.estimate_robot_noise:
            if it == 0:
                kappa, chain.scale = kappa_new, max(s_edge * np.sqrt(kappa_new), 1e-3)
                continue
            break
        Ainv = np.linalg.pinv(sol.normal_matrix)
        Jg, Jv = sol.jacobian if sol.jacobian is not None else prob.evaluate(x, intr0)[1:]
        new = []
        for rows, sig in ((rows_r, sig_r), (rows_t, sig_t)):
            Jr = prob.dense_rows(Jg, Jv, rows)
            red = max(len(rows) - float(np.sum((Jr @ Ainv) * Jr)), 1.0)
            chi2 = float(np.sum((sol.fun[rows] / chain.scale) ** 2))
            new.append(sig * np.sqrt(chi2 / red))
        new_r, new_t = max(new[0], np.radians(1e-4)), max(new[1], 1e-6)
        new_scale = max(s_edge * np.sqrt(kappa_new), 1e-3)
        done = (abs(new_r / sig_r - 1) < 0.05 and abs(new_t / sig_t - 1) < 0.05
                and abs(new_scale / chain.scale - 1) < 0.05)
        sig_r, sig_t = new_r, new_t
        chain.scale, kappa = new_scale, kappa_new
        if done:
            break
    chain.sigma_rot, chain.sigma_trans = sig_r, sig_t
    return sol, kappa, np.linalg.pinv(sol.normal_matrix) if Ainv is None else Ainv, passes


def _intrinsics_share(s: _Setup, views: list[ViewData], opt: CalibrationOptions, x: np.ndarray, s2: float,
                      kappa: float) -> tuple[np.ndarray, dict[str, float]]:
    """The held intrinsics' covariance carried into X and Y (over the parameters of ``s.prob``)
    and the intrinsics' own sigmas from the images alone (module docstring)."""
    prob = s.prob
    intr, shape_v, poses, offsets = prob.unpack(x, s.intr0)
    full = ChainProblem(views, s.free, opt.edge_offsets, s.chain, LOSS_SCALE, s.shape, s.frame, s.lens)
    xf = full.pack_chain(intr, [p.copy() for p in poses], offsets, prob.chain_params(x), shape_v)
    ff, Jg_f, Jv_f = full.evaluate(xf, intr)
    wf = full.robust_weights(ff, LOSS_SCALE)
    Af, _ = full.normal_equations(ff, Jg_f, Jv_f, wf)
    wi = wf.copy()
    wi[full.n_robust:] = 0.0
    Ai, _ = full.normal_equations(ff, Jg_f, Jv_f, wi)
    nf = len(full.free)
    cov_th = np.linalg.pinv(Ai)[:nf, :nf] * s2 * kappa
    S = -np.linalg.pinv(Af[nf:, nf:]) @ Af[nf:, :nf]
    std = {full.names[i]: float(np.sqrt(max(cov_th[k, k], 0.0))) for k, i in enumerate(full.free)}
    return S @ cov_th @ S.T, std


def _residual_figures(prob: ChainProblem, f: np.ndarray) -> tuple[float, np.ndarray, list[np.ndarray],
                                                                  list[np.ndarray]]:
    """(RMS, per-view RMS, per-view edge residuals, per-view corner residuals (observed - predicted));
    the RMS of edge distances, or of corner reprojection errors without edges."""
    er = f[: prob.n_edge]
    edge_res = [er[s] for s in prob.edge_slices]
    cr = f[prob.n_edge:prob.n_robust].reshape(-1, 2)
    if prob.n_edge:
        rms = float(np.sqrt(np.mean(er**2)))
        view_rms = np.array([np.sqrt(np.mean(r * r)) if len(r) else 0.0 for r in edge_res])
    else:
        rms = float(np.sqrt(np.mean(np.sum(cr**2, 1))))
        view_rms = np.array([float(np.sqrt(np.mean(np.sum(cr[prob.view_of_corner == i] ** 2, 1))))
                             for i in range(prob.nv)])
    return rms, view_rms, edge_res, [-cr[prob.view_of_corner == i] for i in range(prob.nv)]


def refine_chain(views: list[ViewData], start: ChainStart, opt: CalibrationOptions, he: HandEyeOptions,
                 target: Target, origin: tuple[float, float], warm: np.ndarray | None = None) -> ChainSolution:
    """The joint refinement with the robot chain as a measurement (module docstring); the arm's
    sigmas by variance components (iterated) when ``he.estimate_robot_noise``. ``warm``: the first
    pass's start (:func:`_variance_components`), in the layout of :meth:`~.chain.ChainProblem.pack_chain`."""
    s = _setup(views, start, opt, he, target, origin)
    prob = s.prob
    sol, kappa, Ainv, passes = _variance_components(s, views, he, warm)
    x, f, w = sol.x, sol.fun, sol.weights
    intr, _, poses, offsets = prob.unpack(x, s.intr0)
    xy = prob.chain_params(x)
    n_rob = prob.n_robust
    s2 = float(np.sum(w[:n_rob] * f[:n_rob] ** 2) / max(n_rob - len(x), 1)) if n_rob else 1.0
    cov = Ainv * s2 * kappa
    std = {prob.names[i]: float(np.sqrt(max(cov[k, k], 0.0))) for k, i in enumerate(prob.free)}
    if he.intrinsics == "hold":
        cov_i, std = _intrinsics_share(s, views, opt, x, s2, kappa)
    else:
        cov_i = np.zeros_like(cov)  # estimated with the chain: their share is in cov
    cov_a = arm_field_share(prob, x, s.intr0, sol.normal_matrix, start.M, he, A_pinv=Ainv) if he.arm_accuracy_mm > 0 \
        else np.zeros_like(cov)
    rms, view_rms, edge_res, corner_res = _residual_figures(prob, f)
    # the robot error the data imply: the estimated sigmas, or the RMS of the disagreements per axis
    if he.estimate_robot_noise:
        err_mm, err_deg = 1000 * s.chain.sigma_trans, float(np.degrees(s.chain.sigma_rot))
    else:
        drv, dt = prob.chain_deltas(xy, poses)
        err_mm, err_deg = 1000 * float(np.sqrt(np.mean(dt**2))), float(np.degrees(np.sqrt(np.mean(drv**2))))
    K, D = camera_from_intrinsics(intr)
    return ChainSolution(
        X=Transform.from_rotvec(xy[0:3], xy[3:6]), Y=Transform.from_rotvec(xy[6:9], xy[9:12]),
        poses=[Transform.from_rotvec(p[:3], p[3:6]) for p in poses], K=K, D=D, std=std, rms=rms, offsets=offsets,
        view_rms=view_rms, edge_residuals=edge_res, corner_residuals=corner_res, robot_error_mm=err_mm,
        robot_error_deg=err_deg, covariance=spread_of(cov, xy, prob.n_base),
        intrinsics_share=spread_of(cov_i, xy, prob.n_base), arm_share=spread_of(cov_a, xy, prob.n_base),
        success=bool(sol.success), passes=passes)


def refine_chain_xy(views: list[ViewData], start: ChainStart, opt: CalibrationOptions, he: HandEyeOptions,
                    target: Target, origin: tuple[float, float]) -> tuple[Transform, Transform]:
    """X and Y of the joint refinement only (no covariance): what the jackknife re-solves."""
    s = _setup(views, start, opt, he, target, origin)
    sol, _, _, _ = _variance_components(s, views, he)
    xy = s.prob.chain_params(sol.x)
    return Transform.from_rotvec(xy[0:3], xy[3:6]), Transform.from_rotvec(xy[6:9], xy[9:12])


def jackknife_spread(views: list[ViewData], start: ChainStart, opt: CalibrationOptions, he: HandEyeOptions,
                     target: Target, origin: tuple[float, float]) -> Spread:
    """Per-axis sigmas of X and Y (mm, deg) from a delete-a-group jackknife: the views in
    ``he.jackknife_groups`` interleaved groups, the joint estimate without each group (from the full
    solution ``start``, the arm's sigmas held at ``he``'s), var = (g - 1) / g sum (theta_-k - mean)^2.
    It sees what the residuals' covariance does not: detection biases that differ from view to view,
    the arm's systematic errors."""
    g = he.jackknife_groups
    he_k = replace(he, estimate_robot_noise=False, jackknife_groups=0)
    xs, ys = [], []
    for k in range(g):
        keep = [i for i in range(len(views)) if i % g != k]
        sub = ChainStart(start.X, start.Y, [start.C[i] for i in keep], [start.M[i] for i in keep], start.calibration)
        Xk, Yk = refine_chain_xy([views[i] for i in keep], sub, opt, he_k, target, origin)
        xs.append(Xk)
        ys.append(Yk)

    def spread(ts: list[Transform], ref: Transform) -> tuple[np.ndarray, np.ndarray]:
        dt = np.array([1000 * (t.translation - ref.translation) for t in ts])
        dr = np.array([np.degrees((t.rotation * ref.rotation.inv()).as_rotvec()) for t in ts])
        f = (g - 1) / g
        return np.sqrt(f * np.sum((dt - dt.mean(0)) ** 2, 0)), np.sqrt(f * np.sum((dr - dr.mean(0)) ** 2, 0))

    (x_mm, x_deg), (y_mm, y_deg) = spread(xs, start.X), spread(ys, start.Y)
    return Spread(x_mm, x_deg, y_mm, y_deg)
