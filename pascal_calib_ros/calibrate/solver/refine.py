"""Joint nonlinear refinement: the robust fit of a :class:`~.problem.Problem` (intrinsics, lens
model, poses, edge offsets, optionally the printed target's shape) with outlier rejection, and its
result with the parameters' covariance (:mod:`.covariance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...geometry import DISTORTION_CHOICES, Camera
from .covariance import correlation_factors, row_variances, sandwich_covariance
from .lm import DEFAULT_LM, LMOptions, LMResult, levenberg_marquardt
from .observations import ViewData
from .problem import SHAPE_NAMES, Problem, camera_from_intrinsics, intrinsic_names


@dataclass
class RefineResult:
    K: np.ndarray
    D: np.ndarray
    poses: list[np.ndarray]  # per view parameters (5 or 6)
    offsets: np.ndarray  # per view edge offset, px
    std: dict[str, float]  # standard deviation of each free intrinsic
    view_rms: np.ndarray  # per view RMS of edge residuals, px
    view_corner_rms: np.ndarray
    rms: float
    residuals: list[np.ndarray]  # per view edge residuals (signed, px)
    cost: float
    nfev: int
    success: bool
    message: str
    shape: dict[str, float] = field(default_factory=dict)  # SHAPE_NAMES -> value (0 when fixed)
    shape_std: dict[str, float] = field(default_factory=dict)  # estimated shape parameters only
    model: str = "plumb_bob"  # ROS distortion_model of D
    # correlation of the estimated pitch ratio with the aspect ratio fy / fx (a mis-scaled print and non-square pixels
    # look alike unless views are tilted strongly about both axes)
    pitch_aspect_correlation: float = 0.0
    # the solution vector, the problem that defines it and the parameters' covariance (uncertainty.py)
    x: np.ndarray | None = None
    problem: Problem | None = None
    intr0: np.ndarray | None = None
    covariance: np.ndarray | None = None
    kappa: tuple[float, float] = (1.0, 1.0)  # correlation factors of the edge and the corner rows
    corner_residuals: list[np.ndarray] = field(default_factory=list)  # per view (M, 2), observed - predicted
    # the observations the solution rests on (outliers removed; their counts in each ViewData)
    views: list[ViewData] = field(default_factory=list)
    robust: bool = True  # soft-L1 loss (False: least squares)
    # the first round, before any observation was rejected: its observations and its solution (a warm start's)
    first_views: list[ViewData] = field(default_factory=list)
    first_x: np.ndarray | None = None

    def camera_of(self, x: np.ndarray) -> Camera:
        """The camera of a parameter vector of :attr:`problem`."""
        assert self.problem is not None and self.intr0 is not None
        K, D = camera_from_intrinsics(self.problem.unpack(x, self.intr0)[0])
        return Camera(K, D, 0, 0, self.model)

    def view_poses_of(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R (V, 3, 3), t (V, 3)) of the views for a parameter vector of :attr:`problem`."""
        assert self.problem is not None and self.intr0 is not None
        R, _, t = self.problem.rotations(self.problem.unpack(x, self.intr0)[2])
        return R, t

    def target_distance(self) -> float:
        """Median distance (m) from the camera to the observed target's centre (the middle of the
        observed features' extent on the sheet) over the views."""
        assert self.x is not None and self.problem is not None
        R, t = self.view_poses_of(self.x)
        xm, ym = self.problem.frame[:2]
        return float(np.median(np.linalg.norm(R[:, :, 0] * xm + R[:, :, 1] * ym + t, axis=1)))


# outlier rejection (mrcal's, per view and kind): a residual beyond OUTLIER_K robust standard deviations
# of its group (1.4826 x the median absolute residual) is dropped and the fit repeated; never below
# MIN_OUTLIER_PX (noise-free data), nor in groups of fewer than MIN_OUTLIER_GROUP rows. A group that
# would lose more than MAX_OUTLIER_FRACTION of its observations is not trimmed: the view itself is bad
# (a moved or misdetected view), which the pipeline's view test catches
OUTLIER_K = 5.0
MIN_OUTLIER_PX = 0.05
MIN_OUTLIER_GROUP = 8
MAX_OUTLIER_FRACTION = 0.25
MAX_REJECTION_ROUNDS = 4


def _outliers(r: np.ndarray, scale_of: np.ndarray, k: float, already: int) -> np.ndarray:
    """Rows of one group whose magnitude ``r`` exceeds k robust standard deviations (from the
    residual components ``scale_of``), unless that would take more than MAX_OUTLIER_FRACTION of
    the group's observations (``already`` rejected before)."""
    if len(r) < MIN_OUTLIER_GROUP:
        return np.zeros(len(r), bool)
    bad = r > max(k * 1.4826 * float(np.median(np.abs(scale_of))), MIN_OUTLIER_PX)
    if already + bad.sum() > MAX_OUTLIER_FRACTION * (len(r) + already):
        return np.zeros(len(r), bool)
    return bad


def outlier_masks(prob: Problem, f: np.ndarray, k: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per view, (edge points, corners) whose residual exceeds ``k`` robust standard deviations of
    that view's residuals of their kind (a corner by the length of its 2-vector residual)."""
    out = []
    corner_res = f[prob.n_edge:prob.n_edge + 2 * prob.n_corner].reshape(-1, 2)
    for v, sl in enumerate(prob.edge_slices):
        r = f[sl]
        c = corner_res[prob.view_of_corner == v]
        view = prob.views[v]
        out.append((_outliers(np.abs(r), r, k, view.rejected_edges),
                    _outliers(np.hypot(c[:, 0], c[:, 1]), c, k, view.rejected_corners)))
    return out


def refine(views: list[ViewData], K0: np.ndarray, D0: np.ndarray, poses0: list[np.ndarray], dof: int,
           distortion: str = "plumb_bob", zero_skew: bool = True, use_offsets: bool = True,
           loss_scale: float = 0.3, max_iter: int = 60, shape: tuple[str, ...] = (),
           shape_frame: tuple[float, float, float, float] | None = None, outlier_k: float = OUTLIER_K,
           x0: np.ndarray | None = None, lm: LMOptions = DEFAULT_LM) -> RefineResult:
    """Robust least squares over K, D, poses, offsets and the named shape parameters (module
    docstring); observations beyond ``outlier_k`` robust standard deviations of their view are
    rejected and the fit repeated until none is left (0: keep every observation). A view may have
    edge points, corners or both. ``loss_scale`` is the soft-L1 scale in px (inf: least squares).

    ``shape_frame`` is (x mid, y mid, x half-width, y half-width) of the warp in the local frame
    (default: the extent of the observed circles); the shape starts flat and true to scale, and
    shape parameters not named stay so. ``x0``: the start as a whole (:meth:`Problem.pack`'s layout; a
    warm start, with ``lm`` :data:`~.lm.WARM_START`) instead of K0, D0, the poses and zero offsets."""
    if distortion not in DISTORTION_CHOICES:
        raise ValueError(f"unknown distortion model {distortion!r}: {', '.join(DISTORTION_CHOICES)}")
    lens, free_d = DISTORTION_CHOICES[distortion]
    names = intrinsic_names(lens)
    unknown = [s for s in shape if s not in SHAPE_NAMES]
    if unknown:
        raise ValueError(f"unknown target shape parameter(s) {unknown}: choose from {', '.join(SHAPE_NAMES)}")
    free = ("fx", "fy", "cx", "cy") + (() if zero_skew else ("skew",)) + free_d
    prob = Problem(views, dof, free, use_offsets, loss_scale, tuple(shape), shape_frame, lens)
    D0 = np.asarray(D0, float).reshape(-1)
    if len(D0) != lens.n:
        raise ValueError(f"start D has {len(D0)} coefficients; {lens.name} has {lens.n}")
    intr0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], 0.0 if zero_skew else K0[0, 1], *D0])
    for name in names[5:]:
        if name not in free:  # coefficients the model does not estimate are held at zero
            intr0[names.index(name)] = 0.0
    start = prob.pack(intr0, poses0, np.zeros(len(views))) if x0 is None else np.asarray(x0, float)
    sol = levenberg_marquardt(prob, start, intr0, loss_scale, max_iter=max_iter, options=lm)
    first_views, first_x = views, sol.x
    for _ in range(MAX_REJECTION_ROUNDS if outlier_k > 0 else 0):
        masks = outlier_masks(prob, sol.fun, outlier_k)
        if not any(e.any() or c.any() for e, c in masks):
            break
        views = [v.without(e, c) for v, (e, c) in zip(views, masks, strict=True)]
        prob = Problem(views, dof, free, use_offsets, loss_scale, tuple(shape), prob.frame, lens)
        sol = levenberg_marquardt(prob, sol.x, intr0, loss_scale, max_iter=max_iter, options=lm)
    res = _refine_result(prob, sol, intr0, loss_scale)
    res.first_views, res.first_x = first_views, first_x
    return res


def _refine_result(prob: Problem, sol: LMResult, intr0: np.ndarray, loss_scale: float) -> RefineResult:
    """The solution of a refinement with its residuals per view and the parameters' covariance (the
    M-estimator's sandwich with per-view noise and correlated residuals, :mod:`.uncertainty`)."""
    views = prob.views
    intr_, shape_v, poses, offsets = prob.unpack(sol.x, intr0)
    K, D = camera_from_intrinsics(intr_)
    er = sol.fun[: prob.n_edge]
    per_view = [er[sl] for sl in prob.edge_slices]
    corner_rms = np.zeros(len(views))
    corner_res = [np.zeros((0, 2)) for _ in views]
    if prob.n_corner:
        cr = -sol.fun[prob.n_edge:prob.n_edge + 2 * prob.n_corner].reshape(-1, 2)  # observed - predicted
        for i in range(len(views)):
            sel = prob.view_of_corner == i
            if sel.any():
                corner_res[i] = cr[sel]
                corner_rms[i] = float(np.sqrt(np.mean(np.sum(cr[sel] ** 2, 1))))
    # a view's RMS: of its edge distances, or of its corners' reprojection errors when it has no edges
    view_rms = np.array([np.sqrt(np.mean(r * r)) if len(r) else corner_rms[i] for i, r in enumerate(per_view)])
    rms = float(np.sqrt(np.mean(er * er))) if len(er) else float(np.sqrt(np.mean(corner_rms**2)))
    std: dict[str, float] = {}
    shape_std: dict[str, float] = {}
    corr = 0.0
    cov: np.ndarray | None = None
    kappa = correlation_factors(prob, views, sol.fun)
    names = prob.names
    try:
        Jg, Jv = sol.jacobian if sol.jacobian is not None else prob.evaluate(sol.x, intr0)[1:]
        psi, dpsi = prob.loss_derivatives(sol.fun, loss_scale)
        var = row_variances(prob, views, sol.fun, psi, len(sol.x))
        cov = sandwich_covariance(prob, sol.fun, Jg, Jv, dpsi, var)
        for k, idx in enumerate(prob.free):
            std[names[idx]] = float(np.sqrt(max(cov[k, k], 0.0)))
        for k, idx in enumerate(prob.shape_idx):
            j = len(prob.free) + k
            shape_std[SHAPE_NAMES[idx]] = float(np.sqrt(max(cov[j, j], 0.0)))
            if SHAPE_NAMES[idx] == "pitch_ratio" and {0, 1} <= set(prob.free):
                g = np.zeros(len(cov))  # d(fy - a fx): the aspect ratio a = fy / fx, linearised
                g[prob.free.index(1)], g[prob.free.index(0)] = 1.0, -K[1, 1] / K[0, 0]
                corr = float(cov[j] @ g / np.sqrt(max(cov[j, j] * (g @ cov @ g), 1e-300)))
    except np.linalg.LinAlgError:
        pass
    return RefineResult(K=K, D=D, poses=[p.copy() for p in poses], offsets=offsets, std=std, view_rms=view_rms,
                        view_corner_rms=corner_rms, rms=rms, residuals=per_view, cost=float(sol.cost),
                        nfev=int(sol.nfev), success=bool(sol.success), message=str(sol.message),
                        shape=dict(zip(SHAPE_NAMES, map(float, shape_v), strict=True)), shape_std=shape_std,
                        model=prob.lens.name, pitch_aspect_correlation=float(corr), x=sol.x, problem=prob,
                        intr0=intr0, covariance=cov, kappa=kappa, corner_residuals=corner_res, views=views,
                        robust=bool(np.isfinite(loss_scale)))
