"""What a candidate view would add to a calibration: the projection uncertainty over the whole
image that would follow if it were captured, predicted from the current estimate.

**The figure of merit.** mrcal's projection uncertainty (:mod:`..analysis.uncertainty`): a pixel's
ray, at the median distance d from the camera to the observed target's centre, carried into every
view's target frame, averaged back and projected with the perturbed parameters. To first order the
average of the views' perturbed poses moves the point by a rigid motion, dp = w x p + tau, with w =
(1/N) sum_i W_i drv_i and tau = (1/N) sum_i (dt_i + t_i x W_i drv_i) (W_i maps a change of view i's
rotation vector to the small rotation it makes: dR_i R_i^T = [W_i drv_i]x). So the pixel moves by
G(u) dr with dr = (free intrinsics, w, tau) = L dx and G(u) = [dq/dintrinsics, -dq/dX [p]x, dq/dX]
(2 x k). Its covariance is G (L Sigma L^T) G^T and its standard deviation in the worst direction
sqrt(lambda_max). Only the k x k matrix L Sigma L^T depends on the views; G is computed once per
calibration, analytically (:func:`..geometry.camera.project_with_jacobians`), on the grid of
:func:`..geometry.image_field.grid_pixels` over the whole image. (dq/dX scales as 1/d: a candidate
that changes the median distance rescales the tau columns.)

**A new view.** Sigma is the M-estimator's sandwich A^-1 B A^-1
(:func:`..calibrate.covariance.sandwich_covariance`: A = J^T diag(psi') J, B = J^T V J, V the rows'
variances kappa mean_g(psi^2)). A view n adds rows J_n =
[Jg_n, Jv_n] (globals, its own pose): A' = [[A + E^T U E, E^T Gv], [Gv^T, Ann]] with
U = Jg^T Jg, Gv = Jg^T Jv, Ann = Jv^T Jv, and B' likewise with the rows' variances. With L'
the readout over N + 1 views, Z = A'^-1 L'^T is found by eliminating the new pose (its Schur
complement on the globals, S = U - Gv Ann^-1 Gv^T) and the Woodbury identity on the old
problem, (A + E^T S E)^-1 = A^-1 - A^-1 E^T (I + S H)^-1 S E A^-1 with H = E A^-1 E^T, so that
every candidate costs a few products of (P x globals) and (globals x k) matrices; then
L' Sigma' L'^T = Z_o^T B Z_o + Z_n'^T B_n Z_n' (Z_n' = [E Z_o; Z_n]). This is the approach of
Calibration Wizard (Peng & Sturm, ICCV 2019: Schur complement of the next pose's Jacobian,
the intrinsics' expected covariance), of pose_calib (Rojtberg & Kuijper, ISMAR 2018) and
AprilCal (Richardson, Strom & Olson, IROS 2013: the worst expected reprojection error over the
image as the score, stopping at the accuracy asked for), here with the sandwich covariance,
mrcal's whole-image projection uncertainty and the circles' edges as the measurements.

The candidate's rows are synthesised at the current estimate (:mod:`.view_synthesis`); their
noise is modelled from the current views' per-row variances (the correlation factor kappa
included): the edges' as a power of the imaged circles' size (:class:`NoiseModel`), the corners'
as their median. Nothing here is a measurement: **done** is decided on the
real projection uncertainty recomputed after a view was captured, never on a prediction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ...calibrate import Problem, RefineResult, ViewData
from ...geometry import Camera, ImageSize, grid_pixels, grid_shape, project_with_jacobians


@dataclass(frozen=True)
class Linearisation:
    """A solved problem at its solution: what the prediction needs (plain data).

    ``var`` (rows,) the rows' variances (the meat of the M-estimator's sandwich), ``w`` their
    weights in its bread (psi', :meth:`..calibrate.problem.Problem.loss_derivatives`); ``extra``
    (e, P) further linear readouts of the global parameters reported beside the projection (e.g.
    the hand-eye transform's six parameters; a new view's pose does not enter them)."""

    problem: Problem
    x: np.ndarray
    intr0: np.ndarray
    var: np.ndarray
    w: np.ndarray
    model: str  # the lens model's ROS name
    extra: np.ndarray | None = None

    @staticmethod
    def of_refinement(res: RefineResult) -> Linearisation:
        """The linearisation behind a :class:`RefineResult` (its problem, solution and noise)."""
        if res.x is None or res.problem is None or res.intr0 is None:
            raise ValueError("the refinement carries no solution to predict from")
        prob = res.problem
        f, _, _ = prob.evaluate(res.x, res.intr0, jac=False)
        psi, dpsi = prob.loss_derivatives(f, prob.loss_scale)
        var = np.ones(len(f))
        n_img = prob.n_edge + 2 * prob.n_corner
        var[:n_img] = group_variances(prob, psi, res.kappa, len(res.x))
        return Linearisation(prob, res.x, res.intr0, var, dpsi, res.model)


def group_variances(prob: Problem, psi: np.ndarray, kappa: tuple[float, float], n_params: int) -> np.ndarray:
    """:func:`..calibrate.covariance.row_variances` with the refinement's correlation factors
    ``kappa`` (edges, corners) instead of estimating them again: per row kappa s_g^2 N / (N - P),
    s_g^2 the mean of psi(r)^2 (the loss's derivative) over its view's edge rows or corner rows."""
    n_e, n_c = prob.n_edge, 2 * prob.n_corner
    dof_scale = (n_e + n_c) / max(n_e + n_c - n_params, 1)
    var = np.zeros(n_e + n_c)
    groups = [(np.arange(s.start, s.stop), kappa[0]) for s in prob.edge_slices]
    vc = np.repeat(prob.view_of_corner, 2)
    groups += [(n_e + np.flatnonzero(vc == v), kappa[1]) for v in range(prob.nv)] if n_c else []
    for rows, kap in groups:
        if len(rows):
            var[rows] = kap * dof_scale * float(np.mean(psi[rows] ** 2))
    return var


def rotation_maps(prob: Problem, x: np.ndarray, intr0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per view W_i (V, 3, dof - 3): the small rotation per unit change of its rotation
    parameters (dR R^T = [W drv]x), and the translations t_i (V, 3)."""
    poses = prob.unpack(x, intr0)[2]
    return pose_rotation_maps(prob, poses)


def pose_rotation_maps(prob: Problem, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rotation_maps` of pose parameter rows (V, dof)."""
    R, dR, t = prob.rotations(np.asarray(poses, float).reshape(-1, prob.dof))
    S = dR @ np.transpose(R, (0, 2, 1))[:, None]  # (V, nr, 3, 3) skew matrices
    W = np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], -1)  # (V, nr, 3)
    return np.transpose(W, (0, 2, 1)), t


def pose_readout(W: np.ndarray, t: np.ndarray, per_view: int) -> np.ndarray:
    """(V, 6, per_view): rows (w, tau) of the rigid motion a change of each view's parameters
    makes, dp = w x p + tau, w = W drv, tau = dt + t x W drv (module docstring)."""
    nv, _, nr = W.shape
    out = np.zeros((nv, 6, per_view))
    out[:, :3, :nr] = W
    tx = np.zeros((nv, 3, 3))
    tx[:, 0, 1], tx[:, 0, 2], tx[:, 1, 2] = -t[:, 2], t[:, 1], -t[:, 0]
    tx[:, 1, 0], tx[:, 2, 0], tx[:, 2, 1] = t[:, 2], -t[:, 1], t[:, 0]
    out[:, 3:, :nr] = tx @ W
    out[:, 3:, nr:nr + 3] = np.eye(3)
    return out


def sigma_worst_direction(G: np.ndarray, C: np.ndarray) -> np.ndarray:
    """sqrt(lambda_max(G C G^T)) per pixel: G (M, 2, k), C (..., k, k) -> (..., M)."""
    GC = np.einsum("mak,...kl->...mal", G, C)
    a = np.einsum("...mk,mk->...m", GC[..., 0, :], G[:, 0])
    b = np.einsum("...mk,mk->...m", GC[..., 0, :], G[:, 1])
    d = np.einsum("...mk,mk->...m", GC[..., 1, :], G[:, 1])
    lam = 0.5 * (a + d) + np.sqrt(np.maximum(0.25 * (a - d) ** 2 + b * b, 0.0))
    return np.sqrt(np.maximum(lam, 0.0))


@dataclass(frozen=True)
class Prediction:
    """Per candidate: the worst projection sigma over the image (px) and the covariance of the
    readout (free intrinsics, w, tau, extra) that would follow."""

    sigma_px: np.ndarray  # (C,)
    readout_cov: np.ndarray  # (C, k, k)
    distance: np.ndarray  # (C,) m, the median view distance with the candidate


class ViewPredictor:
    """The projection uncertainty now and after one more view (module docstring), for one
    linearised calibration. ``step`` is the grid's spacing (default: the image's larger side / 40,
    as :func:`..analysis.uncertainty.projection_uncertainty`)."""

    def __init__(self, lin: Linearisation, size: ImageSize, step: float | None = None):
        width, height = size
        self.lin, self.size, self.width, self.height = lin, size, width, height
        prob = self.prob = lin.problem
        self.step = step or max(size) / 40.0
        f, Jg, Jv = prob.evaluate(lin.x, lin.intr0)
        self.A, _ = prob.normal_equations(f, Jg, Jv, lin.w)
        self.B, _ = prob.normal_equations(f, Jg, Jv, lin.var)
        self.Ainv = inverse_spd(self.A)
        self.nI, self.ng, self.pv, self.nv = len(prob.free), prob.ng, prob.per_view, prob.nv
        W, t = rotation_maps(prob, lin.x, lin.intr0)
        self.t_views = t
        n_x = len(lin.x)
        Lv = np.zeros((6, n_x))
        for i, li in enumerate(pose_readout(W, t, self.pv)):
            s = self.ng + i * self.pv
            Lv[:, s:s + self.pv] = li / self.nv
        EI = np.zeros((self.nI, n_x))
        EI[:, :self.nI] = np.eye(self.nI)
        extra = lin.extra if lin.extra is not None else np.zeros((0, n_x))
        self.n_extra = len(extra)
        self.L = np.concatenate([EI, Lv, extra])  # readout of the current views
        self.k = len(self.L)
        self.cov_now = self.L @ self.Ainv @ self.B @ self.Ainv @ self.L.T
        self.distances = centre_distances(prob, prob.unpack(lin.x, lin.intr0)[2])
        self.distance_now = float(np.median(self.distances))
        # with one more view: the old views' share of the mean pose is N / (N + 1)
        R_o = np.concatenate([EI, Lv * self.nv / (self.nv + 1), extra]).T
        self.Y0 = self.Ainv @ R_o
        self.AE = self.Ainv[:, :self.ng]
        self.H = self.AE[:self.ng]
        self.Q00 = self.Y0.T @ self.B @ self.Y0
        BAE = self.B @ self.AE
        self.Q01 = self.Y0.T @ BAE
        self.Q11 = self.AE.T @ BAE
        self.camera = camera_of(prob, lin)
        self.camera_sized = Camera(self.camera.K, self.camera.D, width, height, self.camera.model)
        self.pixels, self.G = self._pixel_jacobians(self.step)
        self.noise = fit_noise_model(prob, lin.var)

    # -- the image ------------------------------------------------------------------------------
    def _pixel_jacobians(self, step: float) -> tuple[np.ndarray, np.ndarray]:
        """Grid pixels (M, 2) with a ray, and G (M, 2, k) at unit distance (tau columns x 1/d)."""
        uv = grid_pixels(self.size, step)
        rays = self.camera.unproject(uv)
        ok = np.all(np.isfinite(rays), 1)
        uv, rays = uv[ok], rays[ok]
        _, dX, dI = project_with_jacobians(rays, self.camera.K, self.camera.D, self.camera.lens)
        G = np.zeros((len(uv), 2, self.k))
        G[:, :, :self.nI] = dI[:, :, self.prob.free]
        px = np.zeros((len(uv), 3, 3))
        px[:, 0, 1], px[:, 0, 2], px[:, 1, 2] = -rays[:, 2], rays[:, 1], -rays[:, 0]
        px[:, 1, 0], px[:, 2, 0], px[:, 2, 1] = rays[:, 2], -rays[:, 1], rays[:, 0]
        G[:, :, self.nI:self.nI + 3] = -dX @ px
        G[:, :, self.nI + 3:self.nI + 6] = dX
        return uv, G

    def grid_jacobians(self, coarse: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """(pixels, G) of the grid, every ``coarse``-th row and column (the outermost kept)."""
        rows, cols = grid_shape(self.size, self.step)
        uv_all = grid_pixels(self.size, self.step)
        keep_r = np.unique(np.r_[np.arange(0, rows, coarse), rows - 1])
        keep_c = np.unique(np.r_[np.arange(0, cols, coarse), cols - 1])
        sel = (keep_r[:, None] * cols + keep_c[None, :]).ravel()
        want = {tuple(p) for p in uv_all[sel]}
        mask = np.array([tuple(p) in want for p in self.pixels])
        return self.pixels[mask], self.G[mask]

    def sigma_map(self, cov: np.ndarray, distance: float, G: np.ndarray | None = None) -> np.ndarray:
        """Per grid pixel the worst-direction sigma (px) for a readout covariance at ``distance``."""
        G = self.G if G is None else G
        return sigma_worst_direction(_at_distance(G, self.nI, distance), cov)

    def sigma_now(self) -> float:
        """The worst projection sigma over the whole image now (px)."""
        s = self.sigma_map(self.cov_now, self.distance_now)
        return float(np.max(s)) if len(s) else float("nan")

    # -- one more view ----------------------------------------------------------------------------
    def predict(self, views: Sequence[ViewData], poses: np.ndarray, weights: Sequence[np.ndarray] | None = None,
                coarse: int = 1, chain: ChainRows | None = None) -> Prediction:
        """The projection uncertainty after adding each candidate view (its observations
        ``views[c]`` at pose parameters ``poses[c]`` (dof,), local frame), one at a time.
        ``weights[c]`` (rows,) how many real rows each synthetic row stands for; ``coarse``
        evaluates the grid at every coarse-th row and column only; ``chain`` adds rows per view
        from a robot chain (:class:`ChainRows`)."""
        C = len(views)
        if C == 0:
            return Prediction(np.zeros(0), np.zeros((0, self.k, self.k)), np.zeros(0))
        blocks = candidate_blocks(self, views, poses, weights, chain)
        covs = np.stack([self._updated(*b) for b in blocks])
        dist = np.median(np.c_[np.tile(self.distances, (len(poses), 1)), centre_distances(self.prob, poses)], axis=1)
        _, G = self.grid_jacobians(coarse)
        sig = np.array([np.max(sigma_worst_direction(_at_distance(G, self.nI, d), c)) if len(G) else np.nan
                        for c, d in zip(covs, dist, strict=True)])
        return Prediction(sig, covs, dist)

    def _updated(self, UA: np.ndarray, GA: np.ndarray, AA: np.ndarray, UB: np.ndarray, GB: np.ndarray,
                 AB: np.ndarray, ln: np.ndarray) -> np.ndarray:
        """L' Sigma' L'^T after a view with information blocks (U, Gv, Ann) of A and of B and
        new-pose readout ``ln`` (k, per_view) (module docstring)."""
        out = self._update_terms(UA, GA, AA, UB, GB, AB, ln)[3]
        return 0.5 * (out + out.T)

    def _update_terms(self, UA: np.ndarray, GA: np.ndarray, AA: np.ndarray, UB: np.ndarray, GB: np.ndarray,
                      AB: np.ndarray, ln: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_updated`'s Schur complement and Woodbury update: (M_k, Z_g, Z_n, L' Sigma' L'^T
        before symmetrising), for a subclass that adds terms (:mod:`.detector_bias`)."""
        Ai = np.linalg.pinv(AA)
        S = UA - GA @ Ai @ GA.T
        Rn = ln.T  # (pv, k)
        r = GA @ Ai @ Rn
        Mk = r + np.linalg.solve(np.eye(self.ng) + S @ self.H, S @ (self.Y0[:self.ng] - self.H @ r))
        Zg = self.Y0[:self.ng] - self.H @ Mk
        Zn = Ai @ (Rn - GA.T @ Zg)
        old = self.Q00 - self.Q01 @ Mk - Mk.T @ self.Q01.T + Mk.T @ self.Q11 @ Mk
        new = Zg.T @ UB @ Zg + Zg.T @ GB @ Zn + Zn.T @ GB.T @ Zg + Zn.T @ AB @ Zn
        return Mk, Zg, Zn, old + new


@dataclass(frozen=True)
class ChainRows:
    """A robot chain's rows for candidate views: ``rows(poses)`` -> (Jg (V, 6, ng), Jv (V, 6,
    per_view)) at the candidates' pose parameters, each row of variance ``variance``."""

    rows: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    variance: float


GAUGE_RCOND = 1e-10  # Jacobi-scaled eigenvalues below this times the largest are a gauge freedom, not information


def inverse_spd(A: np.ndarray, rcond: float = GAUGE_RCOND) -> np.ndarray:
    """The inverse of a symmetric positive semi-definite normal matrix: by Cholesky when it is
    regular; when its Jacobi-scaled form S = D A D (D = diag(A)^-1/2, so that pixels, metres and
    radians compare) has eigenvalues below ``rcond`` times its largest, the pseudo-inverse on the
    others, D V diag(1 / lambda) V^T D. Such a direction is a gauge freedom no row sees (a single
    ring's rotation about its own axis, taken by the target's pose and every view's pose together
    in an arm's joint problem; scaled eigenvalue 1e-16 where the weakest real one is 1e-6): it gets
    no variance, as in the intrinsic problem, whose ring poses have no such parameter. Cholesky
    alone succeeds on it numerically and gives variances of 1e8 along it."""
    d = np.sqrt(np.clip(np.diag(A), 1e-300, None))
    lam, V = np.linalg.eigh(A / d[:, None] / d[None, :])
    keep = lam > rcond * max(float(lam[-1]), 1e-300)
    if keep.all():
        try:
            c = scipy.linalg.cho_factor(A)
            return np.asarray(scipy.linalg.cho_solve(c, np.eye(len(A))))
        except np.linalg.LinAlgError:
            pass
    Vk = V[:, keep] / d[:, None]
    return np.asarray((Vk / lam[keep]) @ Vk.T)


def centre_distances(prob: Problem, poses: np.ndarray) -> np.ndarray:
    """Distance (m) from the camera to the observed target's centre for pose parameter rows
    (V, dof): where the projection uncertainty is evaluated
    (:meth:`..calibrate.refine.RefineResult.target_distance`, the median of these)."""
    R, _, t = prob.rotations(np.asarray(poses, float).reshape(-1, prob.dof))
    xm, ym = prob.frame[:2]
    return np.linalg.norm(R[:, :, 0] * xm + R[:, :, 1] * ym + t, axis=1)


def _at_distance(G: np.ndarray, nI: int, distance: float) -> np.ndarray:
    out = G.copy()
    out[:, :, nI + 3:nI + 6] /= max(distance, 1e-9)
    return out


def camera_of(prob: Problem, lin: Linearisation) -> Camera:
    """The camera of the linearisation's solution."""
    intr = prob.unpack(lin.x, lin.intr0)[0]
    K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    return Camera(K, intr[5:].copy(), 0, 0, lin.model)


def semi_minor_px(view: ViewData) -> float:
    """Median over a view's circles of the semi-minor axis (px) of its edge points (evenly spread
    along the arc, their covariance has eigenvalues a^2 / 2 and b^2 / 2); NaN without circles."""
    ids = np.asarray(view.circle_ids)
    if len(ids) == 0:
        return float("nan")
    _, group, n = np.unique(ids, return_inverse=True, return_counts=True)
    pts = np.asarray(view.points, float)
    mean = np.stack([np.bincount(group, pts[:, k]) for k in (0, 1)], 1) / n[:, None]
    d = pts - mean[group]
    a, b, c = (np.bincount(group, d[:, i] * d[:, j]) / n for i, j in ((0, 0), (0, 1), (1, 1)))
    lam_min = 0.5 * (a + c) - np.sqrt(0.25 * (a - c) ** 2 + b * b)  # the 2 x 2 covariance's smaller eigenvalue
    keep = n >= 4
    return float(np.median(np.sqrt(2 * np.maximum(lam_min[keep], 0.0)))) if keep.any() else float("nan")


@dataclass(frozen=True)
class NoiseModel:
    """Per-row variance (px^2) of a view's edge rows as a power of its circles' imaged size,
    log var = a + b log(semi-minor axis), fitted over the captured views (small, flat, tilted
    ellipses measure worse: on a ring grid a view of 6 px semi-minor axes is ten times noisier
    than one of 10 px), kept within the observed range (x0.5 .. x2); the corners' median."""

    a: float
    b: float
    lo: float
    hi: float
    corner: float

    def edge_variance(self, semi_minor: float) -> float:
        if not np.isfinite(semi_minor) or semi_minor <= 0:
            return float(np.exp(self.a))  # the fit's value at 1 px: only when b is 0
        return float(np.clip(np.exp(self.a + self.b * np.log(semi_minor)), self.lo, self.hi))


def fit_noise_model(prob: Problem, var: np.ndarray) -> NoiseModel:
    """:class:`NoiseModel` of the current views (slope 0, the median, when fewer than 4 views or
    their sizes hardly differ; the slope kept within [-4, 0])."""
    n_e, n_c = prob.n_edge, 2 * prob.n_corner
    v_e = np.array([float(np.median(var[s])) for s in prob.edge_slices if s.stop > s.start])
    b_e = np.array([semi_minor_px(prob.views[i]) for i, s in enumerate(prob.edge_slices) if s.stop > s.start])
    c = var[n_e:n_e + n_c]
    per_view_c = [float(np.median(c[np.repeat(prob.view_of_corner, 2) == v])) for v in range(prob.nv)
                  if np.any(prob.view_of_corner == v)]
    corner = float(np.median(per_view_c)) if per_view_c else 0.0
    if not len(v_e):
        return NoiseModel(0.0, 0.0, 0.0, 0.0, corner)
    ok = np.isfinite(b_e) & (b_e > 0) & (v_e > 0)
    lv, lb = np.log(v_e[ok]), np.log(b_e[ok])
    slope = 0.0
    if ok.sum() >= 4 and np.ptp(lb) > 0.1:
        slope = float(np.clip(np.polyfit(lb, lv, 1)[0], -4.0, 0.0))
    a = float(np.median(lv - slope * lb)) if ok.any() else float(np.log(max(np.median(v_e), 1e-12)))
    return NoiseModel(a, slope, 0.5 * float(v_e.min()), 2.0 * float(v_e.max()), corner)


def candidate_problem(prob: Problem, views: Sequence[ViewData]) -> Problem:
    """A problem of the same layout (free intrinsics, shape, lens, dof, offsets) over ``views``."""
    free = tuple(prob.names[i] for i in prob.free)
    from ...calibrate import SHAPE_NAMES

    shape = tuple(SHAPE_NAMES[i] for i in prob.shape_idx)
    return Problem(list(views), prob.dof, free, prob.use_offsets, prob.loss_scale, shape, prob.frame, prob.lens)


def candidate_blocks(pred: ViewPredictor, views: Sequence[ViewData], poses: np.ndarray,
                     weights: Sequence[np.ndarray] | None, chain: ChainRows | None
                     ) -> list[tuple[np.ndarray, ...]]:
    """Per candidate the information blocks (U, Gv, Ann) of A and of B and its pose readout."""
    prob = pred.prob
    cp = candidate_problem(prob, views)
    n = len(views)
    offs = np.zeros(n)
    x_c = np.concatenate([pred.lin.x[:prob.n_base],
                          np.concatenate([np.r_[p, o] if prob.use_offsets else p
                                          for p, o in zip(np.asarray(poses, float).reshape(n, -1), offs,
                                                          strict=True)])])
    _, Jg_b, Jv = cp.evaluate(x_c, pred.lin.intr0)
    Jg = np.zeros((len(Jg_b), pred.ng))
    Jg[:, :prob.n_base] = Jg_b
    noise = pred.noise
    row_var = np.concatenate([np.zeros(cp.n_edge), np.full(2 * cp.n_corner, noise.corner)])
    for i, sl in enumerate(cp.edge_slices):
        row_var[sl] = noise.edge_variance(semi_minor_px(views[i]))
    wts = np.ones(len(row_var)) if weights is None else np.zeros(len(row_var))
    if weights is not None:
        for i, rows in enumerate(cp.rows_of_view):
            wts[rows] = np.asarray(weights[i], float)
    W, t = pose_rotation_maps(prob, poses)
    ln = pose_readout(W, t, pred.pv) / (pred.nv + 1)
    cj = chain.rows(np.asarray(poses, float)) if chain is not None else None
    out: list[tuple[np.ndarray, ...]] = []
    for i, rows in enumerate(cp.rows_of_view):
        g, v, wa = Jg[rows], Jv[rows], wts[rows]
        wb = wa * row_var[rows]
        if cj is not None:
            g = np.concatenate([g, cj[0][i]])
            v = np.concatenate([v, cj[1][i]])
            wa = np.r_[wa, np.ones(6)]
            wb = np.r_[wb, np.full(6, chain.variance if chain is not None else 1.0)]
        gw, vw, gb, vb = g * wa[:, None], v * wa[:, None], g * wb[:, None], v * wb[:, None]
        lk = np.zeros((pred.k, pred.pv))
        lk[pred.nI:pred.nI + 6] = ln[i]
        out.append((g.T @ gw, gw.T @ v, v.T @ vw, g.T @ gb, gb.T @ v, v.T @ vb, lk))
    return out
