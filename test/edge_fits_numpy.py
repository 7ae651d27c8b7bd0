"""The edge fits as numpy computed them before the compiled kernels (``detect/edge_kernels.py``):
kept as the reference the kernels are tested against (test_edge_kernels.py). Not part of the
package."""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

_INV_SQRT_2PI = 1.0 / np.sqrt(2 * np.pi)


def fit_step_profiles(prof: np.ndarray, s: np.ndarray, w0: float = 1.0, iterations: int = 8
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fit a + b s + c Phi((s - s0)/w) to each row of ``prof`` (vectorised Levenberg-Marquardt).

    Starts from the moments of the baseline-removed derivative (centroid -> s0, spread -> w).
    Returns s0, w, c and the RMS residual of each profile."""
    n, m = prof.shape
    y = prof.astype(np.float64)
    S = np.broadcast_to(s if s.ndim == 2 else s[None, :], (n, m))  # per-profile offsets allowed
    k = max(2, m // 6)
    lo, hi = y[:, :k].mean(1), y[:, -k:].mean(1)
    g = np.diff(y, axis=1) * np.sign(hi - lo)[:, None]
    g = np.maximum(g - np.median(g, axis=1, keepdims=True), 0.0)
    s_mid = (S[:, :-1] + S[:, 1:]) / 2
    gs = np.maximum(g.sum(1), 1e-9)
    c0 = (g * s_mid).sum(1) / gs
    var = (g * (s_mid - c0[:, None]) ** 2).sum(1) / gs
    w_init = np.clip(np.sqrt(np.maximum(var, 0.0)), 0.3, 0.5 * (S[:, -1] - S[:, 0]))
    w_init = np.where(np.isfinite(w_init), w_init, w0)
    p = np.stack([lo, np.zeros(n), hi - lo, c0, w_init], 1)
    lam = np.full(n, 1e-2)
    ones = np.ones((n, m))

    def model(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = (S - p[:, 3:4]) / p[:, 4:5]
        cdf = ndtr(z)
        return p[:, 0:1] + p[:, 1:2] * S + p[:, 2:3] * cdf, z, cdf

    f, z, cdf = model(p)
    r = y - f
    cost = np.sum(r * r, 1)
    eye = np.eye(5)[None]
    for _ in range(iterations):
        phi = _INV_SQRT_2PI * np.exp(-0.5 * z * z)
        d3 = -p[:, 2:3] * phi / p[:, 4:5]
        J = np.stack([ones, S, cdf, d3, d3 * z], 1)  # (n, 5, m)
        A = J @ J.transpose(0, 2, 1)
        gvec = (J @ r[:, :, None])[..., 0]
        diag = np.einsum("nii->ni", A)
        A_d = A + (lam[:, None] * diag + 1e-9)[:, :, None] * eye
        step = np.linalg.solve(A_d, gvec[..., None])[..., 0]
        pn = p + step
        pn[:, 4] = np.clip(pn[:, 4], 0.15, 50.0)
        fn, zn, cdfn = model(pn)
        rn = y - fn
        cn = np.sum(rn * rn, 1)
        better = cn < cost
        b = better[:, None]
        p = np.where(b, pn, p)
        z = np.where(b, zn, z)
        cdf = np.where(b, cdfn, cdf)
        r = np.where(b, rn, r)
        cost = np.where(better, cn, cost)
        lam = np.where(better, lam * 0.2, lam * 10.0)
    return p[:, 3], p[:, 4], p[:, 2], np.sqrt(cost / m)


def fit_band_profiles(prof: np.ndarray, S: np.ndarray, lo0: np.ndarray, hi0: np.ndarray,
                      w0: float | np.ndarray = 1.0, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Fit a + b s - c [Phi((s - lo)/w_lo) - Phi((s - hi)/w_hi)] (a band of contrast c between two
    blurred edges lo < hi, on a linear ramp) to each row of ``prof`` sampled at the rows of ``S``;
    vectorised Levenberg-Marquardt from the edges ``lo0``, ``hi0`` and blur ``w0`` (per row or one).

    A thin band's two edges share their blurred tails: a single step fitted to one of them is
    pulled towards the other (ring_grid_a4 at 800x600: bands of 3-6 px, by up to 0.3 px, more where
    foreshortening narrows the band, hence the elliptical residual pattern of each ring). Returns
    the parameters (n, 7) [a, b, c, lo, w_lo, hi, w_hi] and each profile's RMS residual."""
    n, m = prof.shape
    # the (n, m) arrays in float32 (half the memory traffic; positions to 1e-6 px), the
    # parameters and the 7 x 7 solves in float64
    y = np.asarray(prof, np.float32)
    S32 = np.asarray(S, np.float32)
    k = max(2, m // 8)
    level = (y[:, :k].mean(1, dtype=np.float64) + y[:, -k:].mean(1, dtype=np.float64)) / 2
    w = np.broadcast_to(np.asarray(w0, float), (n,))
    p = np.stack([level, np.zeros(n), level - y.min(1), lo0, w, hi0, w], 1)
    lam = np.full(n, 1e-2)
    eye = np.eye(7)[None]
    J = np.empty((n, 7, m), np.float32)  # rows: a, b, c, lo, w_lo, hi, w_hi
    J[:, 0] = 1.0
    J[:, 1] = S32

    def model(p: np.ndarray) -> tuple[np.ndarray, ...]:
        q = p.astype(np.float32)
        z_lo, z_hi = (S32 - q[:, 3:4]) / q[:, 4:5], (S32 - q[:, 5:6]) / q[:, 6:7]
        band = ndtr(z_lo) - ndtr(z_hi)
        return q[:, 0:1] + q[:, 1:2] * S32 - q[:, 2:3] * band, z_lo, z_hi, band

    f, z_lo, z_hi, band = model(p)
    r = y - f
    cost = np.sum(r * r, 1, dtype=np.float64)
    for _ in range(iterations):
        c = p[:, 2:3].astype(np.float32) * np.float32(_INV_SQRT_2PI)
        d_lo = c * np.exp(-0.5 * z_lo * z_lo) / p[:, 4:5].astype(np.float32)
        d_hi = -c * np.exp(-0.5 * z_hi * z_hi) / p[:, 6:7].astype(np.float32)
        J[:, 2] = -band
        J[:, 3] = d_lo
        J[:, 4] = d_lo * z_lo
        J[:, 5] = d_hi
        J[:, 6] = d_hi * z_hi
        A = (J @ J.transpose(0, 2, 1)).astype(np.float64)
        g = (J @ r[:, :, None])[..., 0].astype(np.float64)
        diag = np.einsum("nii->ni", A)
        step = np.linalg.solve(A + (lam[:, None] * diag + 1e-9)[:, :, None] * eye, g[..., None])[..., 0]
        pn = p + step
        pn[:, 4] = np.clip(pn[:, 4], 0.15, 50.0)
        pn[:, 6] = np.clip(pn[:, 6], 0.15, 50.0)
        fn, zl, zh, bn = model(pn)
        rn = y - fn
        cn = np.sum(rn * rn, 1, dtype=np.float64)
        better = cn < cost
        b = better[:, None]
        p = np.where(b, pn, p)
        z_lo, z_hi, band, r = np.where(b, zl, z_lo), np.where(b, zh, z_hi), np.where(b, bn, band), np.where(b, rn, r)
        cost = np.where(better, cn, cost)
        lam = np.where(better, lam * 0.2, lam * 10.0)
    return p, np.sqrt(cost / m)




def refine_ellipse_numpy(params: np.ndarray, pts: np.ndarray, iterations: int = 10) -> np.ndarray:
    """The geometric ellipse refinement of geometry.conic.fit_conic as numpy ran it."""
    from pascal_calib_ros.geometry.conic import Ellipse, sampson_distance

    def residual(p: np.ndarray) -> np.ndarray:
        return sampson_distance(Ellipse(*p).to_conic(), pts)

    params = np.asarray(params, float).copy()
    scale = max(params[2], 1e-9)
    prev = np.inf
    for _ in range(iterations):
        r = residual(params)
        cost = float(r @ r)
        J = np.empty((len(pts), 5))
        for k in range(5):
            h = 1e-6 * (scale if k < 4 else 1.0)
            dp = params.copy()
            dp[k] += h
            J[:, k] = (residual(dp) - r) / h
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        new = params + step
        if new[2] <= 0 or new[3] <= 0 or float(np.sum(residual(new) ** 2)) > cost:
            break
        params = new
        if prev - cost < 1e-14 * max(cost, 1e-30):
            break
        prev = cost
    return params
