"""How far a calibration can be trusted: honest parameter covariances and projection uncertainty.

- **Correlated edge residuals.** Neighbouring edge points share pixels and blur (and neighbouring
  checkerboard corners share the sub-pixel locator's bias), so n points hold fewer than n
  independent measurements. The integrated autocorrelation time kappa = 1 + 2 sum_k rho_k of the
  residual sequences along each contour (Geyer's initial positive sequence; Geyer 1992, "Practical
  Markov chain Monte Carlo", Stat. Sci. 7) is the factor by which the variance of a slowly varying
  weighted sum of them exceeds the white-noise value.
- **Parameter covariance.** The fit minimises an unweighted (robust) sum of squares, while the
  noise differs between views (contrast, blur, JPEG) and between edges and corners. The covariance
  of such an estimate is the sandwich A^-1 B A^-1 with A = J^T W J and B = sum_g c_g J_g^T W^2 J_g
  over groups g (the edge rows and the corner rows of each view), c_g = kappa_kind s_g^2 the
  group's residual variance times its correlation factor (White 1980, Econometrica 48;
  heteroscedastic least squares).
- **Projection uncertainty** (mrcal, "Projection uncertainty"): the pixel of a point at a given
  range is uncertain through the intrinsics *and* through the camera's placement relative to the
  views, which the calibration estimates jointly. As mrcal does, the point is carried into every
  view's target frame, back through that view's perturbed pose, averaged over views and projected
  with the perturbed intrinsics; its 2x2 covariance G Sigma G^T (G by central differences over the
  parameters) gives the worst-direction standard deviation sqrt(lambda_max).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from .diagnostics import grid_pixels, grid_shape

# lags (edge points, ~1 px apart) over which edge residuals are taken as correlated noise: blur and
# the profiles' interpolation couple neighbours over 2-4 px (measured autocorrelations fall below
# 0.02 by lag 3-5 on renders); a smooth misfit of the lens model would otherwise count as noise
# correlated over the whole contour and inflate every sigma by its length
EDGE_MAX_LAG = 10

if TYPE_CHECKING:
    from ..geometry.camera import Camera
    from .refine import LeastSquaresProblem, Problem, ViewData


def lag_factor(chunks: list[np.ndarray], circular: bool, max_lag: int = 40) -> float:
    """1 + 2 sum_k rho_k of residual sequences (pooled lag-k autocorrelations, summed while positive:
    Geyer's initial positive sequence): the factor by which correlated neighbours reduce the
    effective number of independent residuals."""
    chunks = [c for c in chunks if len(c) >= 4]
    if not chunks:
        return 1.0
    r0 = sum(float(c @ c) for c in chunks)
    n0 = sum(len(c) for c in chunks)
    if r0 <= 0:
        return 1.0
    var = r0 / n0
    kappa = 1.0
    for k in range(1, max_lag + 1):
        num, cnt = 0.0, 0
        for c in chunks:
            if len(c) < 2 * k + 2:
                continue
            if circular:
                num += float(c @ np.roll(c, -k))
                cnt += len(c)
            else:
                num += float(c[:-k] @ c[k:])
                cnt += len(c) - k
        if cnt == 0:
            break
        rho = num / cnt / var
        if rho <= 0.02:
            break
        kappa += 2 * rho
    return kappa


def correlation_factors(prob: Problem, views: list[ViewData], f: np.ndarray) -> tuple[float, float]:
    """(kappa of the edge rows, kappa of the corner rows): how many times fewer independent
    observations they hold than rows. Edges: along each closed contour of a circle in a view;
    corners: along the rows and the columns of each view's grid (product of the two)."""
    kap_e = kap_c = 1.0
    n_e, n_c = prob.n_edge, prob.n_corner
    if n_e:
        er = f[:n_e]
        chunks: list[np.ndarray] = []
        for v, sl in enumerate(prob.edge_slices):
            r, ids = er[sl], views[v].circle_ids
            if len(r) != len(ids):
                continue
            cut = np.flatnonzero(np.diff(ids)) + 1
            chunks += list(np.split(r, cut))
        kap_e = lag_factor(chunks, circular=True, max_lag=EDGE_MAX_LAG)
    if n_c:
        cr = f[n_e:n_e + 2 * n_c].reshape(-1, 2)
        rows_: list[np.ndarray] = []
        cols_: list[np.ndarray] = []
        for v in range(prob.nv):
            sel = np.flatnonzero(prob.view_of_corner == v)
            obj = views[v].corner_obj
            if len(sel) < 9 or len(obj) != len(sel):
                continue
            xs, ys = np.unique(np.round(obj[:, 0], 6)), np.unique(np.round(obj[:, 1], 6))
            if len(xs) * len(ys) != len(sel):
                continue
            ix = np.searchsorted(xs, np.round(obj[:, 0], 6))
            iy = np.searchsorted(ys, np.round(obj[:, 1], 6))
            grid = np.zeros((len(ys), len(xs), 2))
            grid[iy, ix] = cr[sel]
            for a in range(2):
                rows_ += list(grid[:, :, a])
                cols_ += list(grid[:, :, a].T)
        if rows_:
            kap_c = lag_factor(rows_, circular=False, max_lag=6) * lag_factor(cols_, circular=False, max_lag=6)
    return float(kap_e), float(kap_c)


def correlation_factor(prob: Problem, views: list[ViewData], f: np.ndarray) -> float:
    """One kappa for all edge and corner rows (their row-weighted mean)."""
    kap_e, kap_c = correlation_factors(prob, views, f)
    n_e, n_c = prob.n_edge, 2 * prob.n_corner
    return float((n_e * kap_e + n_c * kap_c) / max(n_e + n_c, 1))


def row_variances(prob: Problem, views: list[ViewData], f: np.ndarray, w: np.ndarray, n_params: int
                  ) -> np.ndarray:
    """Per residual row of the views' observations: kappa_kind s_g^2, s_g^2 the weighted mean
    square residual of its group (one view's edge rows, or its corner rows) scaled by N / (N - P)
    for the parameters the fit absorbed."""
    n_e, n_c = prob.n_edge, 2 * prob.n_corner
    kap_e, kap_c = correlation_factors(prob, views, f)
    n = n_e + n_c
    dof_scale = n / max(n - n_params, 1)
    var = np.zeros(n)
    groups = [(sl, kap_e) for sl in prob.edge_slices]
    if n_c:
        corner_rows = n_e + np.flatnonzero(np.repeat(prob.view_of_corner, 2) >= 0)
        vc = np.repeat(prob.view_of_corner, 2)
        groups += [(corner_rows[vc == v], kap_c) for v in range(prob.nv)]
    for rows, kap in groups:
        r, ww = f[rows], w[rows]
        if np.size(r):
            var[rows] = kap * dof_scale * float(np.sum(ww * r * r) / np.size(r))
    return var


def sandwich_covariance(prob: LeastSquaresProblem, A: np.ndarray, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray,
                        w: np.ndarray, var: np.ndarray) -> np.ndarray:
    """A^-1 (J^T W diag(var) W J) A^-1 over all parameters (module docstring); rows beyond
    ``len(var)`` (e.g. a robot chain's, already in units of their sigma) count with variance 1."""
    v = np.ones(len(f))
    v[:len(var)] = var
    B, _ = prob.normal_equations(f, Jg, Jv, w * w * v)
    Ainv = np.linalg.pinv(A)
    return Ainv @ B @ Ainv


def _jacobian(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Central differences of a vector function f(x) (M,) over the named columns of x: (M, K)."""
    G = np.zeros((len(f(x)), len(columns)))
    for k, j in enumerate(columns):
        h = 1e-6 * max(abs(float(x[j])), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        G[:, k] = (f(xp) - f(xm)) / (2 * h)
    return G


@dataclass
class ProjectionUncertainty:
    """Worst-direction pixel standard deviation of projecting a point at ``distance`` metres."""

    pixels: np.ndarray  # (N, 2) grid over the image
    sigma: np.ndarray  # (N,) px; NaN where the model cannot unproject
    distance: float  # m
    grid_shape: tuple[int, int]  # (rows, cols) of the grid

    def over(self, mask: np.ndarray | None) -> np.ndarray:
        """The finite sigmas of the grid points inside ``mask`` ((H, W) bool; None: all)."""
        s = self.sigma
        if mask is not None:
            u = np.clip(self.pixels[:, 0].astype(int), 0, mask.shape[1] - 1)
            vv = np.clip(self.pixels[:, 1].astype(int), 0, mask.shape[0] - 1)
            s = s[mask[vv, u]]
        return s[np.isfinite(s)]

    def summary(self, mask: np.ndarray | None) -> dict[str, float]:
        s = self.over(mask)
        if not len(s):
            return {"median_px": float("nan"), "worst_px": float("nan"), "distance_m": self.distance}
        return {"median_px": float(np.median(s)), "worst_px": float(np.max(s)), "distance_m": self.distance}


def projection_uncertainty(camera_of: Callable[[np.ndarray], Camera],
                           view_poses_of: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                           x: np.ndarray, cov: np.ndarray, width: int, height: int, distance: float,
                           step: float | None = None) -> ProjectionUncertainty:
    """mrcal's projection uncertainty (module docstring) on a grid of pixels.

    ``camera_of(x)`` is the camera of a parameter vector, ``view_poses_of(x)`` the views' poses
    (R (V, 3, 3) target -> camera, t (V, 3)); ``cov`` the parameters' covariance."""
    step = step or max(width, height) / 40.0
    uv = grid_pixels(width, height, step)
    cam = camera_of(x)
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    p_cam = distance * rays[ok]
    R, t = view_poses_of(x)
    p_loc = np.einsum("vji,vnj->vni", R, p_cam[None, :, :] - t[:, None, :])  # R^T (p - t), per view

    def q(xx: np.ndarray) -> np.ndarray:
        Rx, tx = view_poses_of(xx)
        p = np.mean(p_loc @ np.transpose(Rx, (0, 2, 1)), axis=0) + np.mean(tx, axis=0)  # mean_i R_i p_i + t_i
        return camera_of(xx).project(p)

    active = np.flatnonzero(np.diag(cov) > 0)
    G = _jacobian(lambda xx: q(xx).reshape(-1), x, active).reshape(len(p_cam), 2, len(active))
    C = (G @ cov[np.ix_(active, active)]) @ np.transpose(G, (0, 2, 1))  # G Sigma G^T per point
    lam = np.linalg.eigvalsh(0.5 * (C + np.transpose(C, (0, 2, 1))))[:, -1]
    sigma = np.full(len(uv), np.nan)
    sigma[ok] = np.sqrt(np.maximum(lam, 0.0))
    return ProjectionUncertainty(uv, sigma, float(distance), grid_shape(width, height, step))


def rotation_free_difference_variance(camera_of: Callable[[np.ndarray], Camera],
                                      view_poses_of: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                                      x: np.ndarray, cov: np.ndarray, rays: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Per point (N,): the expected squared length of one calibration's share of a projection
    difference at infinity after the best-fitting rotation is removed (mrcal's projection_diff).

    A ray v at infinity is carried into the views' frames and back (mrcal's mean over frames:
    p = mean_i R_i(x) R_i(x0)^T v) and projected: q(x), with Jacobian G (2N x P) by central
    differences. The rotation fitted jointly over all points removes the part of G dx in the span
    of H (2N x 3, the displacement of every point per small rotation), so what remains is
    M dx with M = (I - H H^+) G, of covariance M Sigma M^T; its 2x2 diagonal blocks' traces are
    returned."""
    R0, _ = view_poses_of(x)
    loc = np.einsum("vji,nj->vni", R0, rays)  # R_i^T v

    def q(xx: np.ndarray) -> np.ndarray:
        Rx, _ = view_poses_of(xx)
        return camera_of(xx).project(np.mean(loc @ np.transpose(Rx, (0, 2, 1)), axis=0)).reshape(-1)

    active = np.flatnonzero(np.diag(cov) > 0)
    G = _jacobian(q, x, active)
    M = G - H @ np.linalg.lstsq(H, G, rcond=None)[0]
    per_row = np.sum((M @ cov[np.ix_(active, active)]) * M, axis=1)
    return per_row.reshape(-1, 2).sum(1)


def rotation_displacements(camera: Camera, rays: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """H (2N x 3): d project(R(w) v) / d w at w = 0 for rays v (N, 3), by central differences."""
    return _jacobian(lambda w: camera.project(Rotation.from_rotvec(w).apply(rays)).reshape(-1), np.zeros(3),
                     np.arange(3))
