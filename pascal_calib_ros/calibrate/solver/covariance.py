"""The covariance of a calibration estimate: the M-estimator sandwich over groups of correlated residuals.

- **Correlated residuals.** Neighbouring edge points share pixels and blur (and neighbouring
  checkerboard corners share the sub-pixel locator's bias), so n points hold fewer than n
  independent measurements. The integrated autocorrelation time kappa = 1 + 2 sum_k rho_k of the
  residual sequences along each contour (Geyer's initial positive sequence; Geyer 1992, "Practical
  Markov chain Monte Carlo", Stat. Sci. 7) is the factor by which the variance of a slowly varying
  weighted sum of them exceeds the white-noise value.
- **Parameter covariance.** The fit minimises an unweighted robust loss rho (soft-L1) of the
  residuals, while the noise differs between views (contrast, blur, JPEG) and between edges and
  corners. The covariance of such an M-estimate is the sandwich A^-1 B A^-1 with
  A = J^T diag(psi'(r)) J and B = sum_g c_g J_g^T J_g over groups g (the edge rows and the corner
  rows of each view), c_g = kappa_kind mean_g(psi(r)^2) the group's variance of the loss's
  derivative psi = rho' times its correlation factor (Huber 1981, "Robust Statistics", sec. 7.6;
  White 1980, Econometrica 48, for the heteroscedastic groups). For least squares psi = r, psi' = 1.

The covariance belongs to the estimator (it depends on its loss), and the hand-eye solver's
sigmas are built on it; what it means in pixels is :mod:`..analysis.uncertainty`.
"""

from __future__ import annotations

import numpy as np

from .lm import LeastSquaresProblem
from .observations import ViewData
from .problem import Problem

# lags (edge points, ~1 px apart) over which edge residuals are taken as correlated noise: blur and
# the profiles' interpolation couple neighbours over 2-4 px (measured autocorrelations fall below
# 0.02 by lag 3-5 on renders); a smooth misfit of the lens model would otherwise count as noise
# correlated over the whole contour and inflate every sigma by its length
EDGE_MAX_LAG = 10


def lag_factor(chunks: list[np.ndarray], circular: bool, max_lag: int = 40) -> float:
    """1 + 2 sum_k rho_k of residual sequences (pooled lag-k autocorrelations, summed while positive:
    Geyer's initial positive sequence): the factor by which correlated neighbours reduce the
    effective number of independent residuals. The lag-k products of all sequences at once (each
    sequence's index shifted by k within it, around it when ``circular``)."""
    chunks = [c for c in chunks if len(c) >= 4]
    if not chunks:
        return 1.0
    a = np.concatenate(chunks)
    lengths = np.array([len(c) for c in chunks])
    r0 = float(np.sum(a * a))  # elementwise sums, not BLAS: the same last bits under every kernel
    if r0 <= 0:
        return 1.0
    var = r0 / len(a)
    start = np.repeat(np.cumsum(lengths) - lengths, lengths)  # each residual's sequence start and length
    length = np.repeat(lengths, lengths)
    pos = np.arange(len(a)) - start
    kappa = 1.0
    for k in range(1, max_lag + 1):
        use = length >= 2 * k + 2
        if circular:
            cnt = int(np.sum(lengths[lengths >= 2 * k + 2]))
            idx = np.flatnonzero(use)
            num = float(np.sum(a[idx] * a[start[idx] + (pos[idx] + k) % length[idx]]))
        else:
            cnt = int(np.sum(lengths[lengths >= 2 * k + 2] - k))
            idx = np.flatnonzero(use & (pos + k < length))
            num = float(np.sum(a[idx] * a[idx + k]))
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


def row_variances(prob: Problem, views: list[ViewData], f: np.ndarray, psi: np.ndarray, n_params: int
                  ) -> np.ndarray:
    """Per residual row of the views' observations: kappa_kind s_g^2, with s_g^2 the mean of psi(r)^2
    over its group (one view's edge rows, or its corner rows; psi the loss's derivative, r for least
    squares) scaled by N / (N - P) for the parameters the fit absorbed: the meat of an
    M-estimator's sandwich (:func:`sandwich_covariance`)."""
    n_e, n_c = prob.n_edge, 2 * prob.n_corner
    kap_e, kap_c = correlation_factors(prob, views, f)
    n = n_e + n_c
    dof_scale = n / max(n - n_params, 1)
    var = np.zeros(n)
    groups = [(np.arange(sl.start, sl.stop), kap_e) for sl in prob.edge_slices]
    if n_c:
        vc = np.repeat(prob.view_of_corner, 2)
        groups += [(n_e + np.flatnonzero(vc == v), kap_c) for v in range(prob.nv)]
    for rows, kap in groups:
        if len(rows):
            var[rows] = kap * dof_scale * float(np.mean(psi[rows] ** 2))
    return var


def sandwich_covariance(prob: LeastSquaresProblem, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray, dpsi: np.ndarray,
                        var: np.ndarray) -> np.ndarray:
    """A^-1 B A^-1 over all parameters: A = J^T diag(psi') J, B = J^T diag(var) J (module docstring;
    ``var`` from :func:`row_variances`); rows beyond ``len(var)`` (e.g. a robot chain's, already in
    units of their sigma) count with variance 1."""
    v = np.ones(len(f))
    v[:len(var)] = var
    A, _ = prob.normal_equations(f, Jg, Jv, dpsi)
    B, _ = prob.normal_equations(f, Jg, Jv, v)
    Ainv = np.linalg.pinv(A)
    return Ainv @ B @ Ainv
