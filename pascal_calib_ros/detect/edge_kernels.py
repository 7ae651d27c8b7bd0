"""Compiled kernels of the edge fits (numba): the blurred-step and the band model fitted to each
intensity profile by Levenberg-Marquardt, one profile after the other in compiled loops.

The math is :func:`.edges.fit_step_profiles` / :func:`.edges.fit_band_profiles` (their docstrings
give the models), step for step: the same start, damping, clipping, acceptance test and
iteration count, in float64 throughout. What changes is where the time goes: numpy evaluated the
model, its Jacobian and the 5 x 5 (7 x 7) normal equations as separate passes over (n, m) arrays
and solved n small systems through LAPACK; here each profile's samples stay in registers and its
system is solved by an unrolled Cholesky factorisation (the damped normal matrix is positive
definite: J Jᵀ plus a positive diagonal).

This module imports numba; :mod:`.edges` imports it on first use (never at package import), and
numba compiles each kernel on its first call and caches the machine code on disk (``cache=True``:
``__pycache__`` beside this file, or numba's per-user cache directory when that is read-only).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
_SQRT1_2 = 1.0 / math.sqrt(2.0)
_FAST = {"contract", "reassoc", "arcp", "nsz"}


_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01  # ln 2 in two parts (Cody & Waite): k ln2_hi is exact
_LN2_LO = 1.90821492927058770002e-10


@intrinsic
def _float_from_bits(typingctx, bits):
    """The float64 whose IEEE-754 bit pattern is the int64 ``bits`` (an LLVM bitcast)."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.float64))

    return sig, codegen


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _exp_nonpositive(v: float) -> float:
    """e^v for v <= 0 (0 below -708), relative error < 1e-13: v = k ln2 + r with |r| <= ln2 / 2
    (Cody-Waite reduction), e^r by its Taylor polynomial to r^12 (remainder < 2e-16), 2^k from
    the exponent bits. Unlike a call to libm's exp, the compiler vectorises loops over it (SIMD):
    it is the one transcendental function of the fits' inner loops."""
    vv = max(v, -708.0)
    k = math.floor(vv * _LOG2E + 0.5)
    r = (vv - k * _LN2_HI) - k * _LN2_LO
    q = 1.0 + r * (1.0 + r * (1 / 2 + r * (1 / 6 + r * (1 / 24 + r * (1 / 120 + r * (1 / 720 + r * (
        1 / 5040 + r * (1 / 40320 + r * (1 / 362880 + r * (1 / 3628800 + r * (1 / 39916800 + r / 479001600)))))))))))
    e = q * _float_from_bits((np.int64(k) + 1023) << 52)  # type: ignore[call-arg]
    return e if v >= -708.0 else 0.0


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _phi_and_cdf(z: float) -> tuple[float, float]:
    """Standard normal density φ(z) and CDF Φ(z) from one exponential: Φ by Abramowitz & Stegun
    7.1.26 (|error of erf| <= 1.5e-7, so |error of Φ| <= 7.5e-8: float32 precision, which the
    band fit in numpy had), φ = exp(-z²/2) / √(2π) (:func:`_exp_nonpositive`). libm's erfc
    costs four exponentials' time, and the fits evaluate Φ at every sample of every iteration."""
    x = abs(z) * _SQRT1_2
    e = _exp_nonpositive(-x * x)
    t = 1.0 / (1.0 + 0.3275911 * x)
    tail = 0.5 * t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))) * e
    return _INV_SQRT_2PI * e, (1.0 - tail if z > 0 else tail)


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _damped_step(A: np.ndarray, gv: np.ndarray, lam: float, k: int, L: np.ndarray, x: np.ndarray) -> None:
    """x = (A + λ diag(A) + 1e-9 I)⁻¹ gv for the k x k normal matrix A given by its lower
    triangle (the Levenberg-Marquardt step of fit_step_profiles / fit_band_profiles, which
    numpy solved by LU): Cholesky into L (k x k scratch; its diagonal holds the reciprocals).
    The damped matrix is positive definite; NaN in the data gives NaN. Inlined where k is a
    constant, so that the compiler unrolls the loops."""
    for i in range(k):
        for j in range(i + 1):
            t = A[i, j]
            if i == j:
                t += lam * A[i, i] + 1e-9
            for q in range(j):
                t -= L[i, q] * L[j, q]
            if i == j:
                L[i, i] = 1.0 / math.sqrt(t) if t > 0 else math.nan
            else:
                L[i, j] = t * L[j, j]
    for i in range(k):  # forward: L y = gv
        t = gv[i]
        for q in range(i):
            t -= L[i, q] * x[q]
        x[i] = t * L[i, i]
    for i in range(k - 1, -1, -1):  # back: Lᵀ x = y
        t = x[i]
        for q in range(i + 1, k):
            t -= L[q, i] * x[q]
        x[i] = t * L[i, i]


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _median_inplace(v: np.ndarray, n: int) -> float:
    """Median of v[:n] (n >= 1); sorts v[:n] in place (insertion sort: n is a profile's length)."""
    for i in range(1, n):
        x = v[i]
        j = i - 1
        while j >= 0 and v[j] > x:
            v[j + 1] = v[j]
            j -= 1
        v[j + 1] = x
    return 0.5 * (v[(n - 1) // 2] + v[n // 2])


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _step_start(y: np.ndarray, s: np.ndarray, w0: float, p: np.ndarray, g: np.ndarray, tmp: np.ndarray) -> None:
    """The step fit's start for one profile y(s) (as fit_step_profiles): plateaus from the first
    and last sixth, edge and width from the moments of the baseline-removed derivative."""
    m = y.shape[0]
    k = max(2, m // 6)
    lo = 0.0
    hi = 0.0
    for i in range(k):
        lo += y[i]
        hi += y[m - k + i]
    lo /= k
    hi /= k
    sgn = 1.0 if hi > lo else (-1.0 if hi < lo else 0.0)
    for i in range(m - 1):
        g[i] = (y[i + 1] - y[i]) * sgn
        tmp[i] = g[i]
    med = _median_inplace(tmp, m - 1)
    gs = 0.0
    c0 = 0.0
    for i in range(m - 1):
        g[i] = max(g[i] - med, 0.0)
        gs += g[i]
        c0 += g[i] * 0.5 * (s[i] + s[i + 1])
    gs = max(gs, 1e-9)
    c0 /= gs
    var = 0.0
    for i in range(m - 1):
        d = 0.5 * (s[i] + s[i + 1]) - c0
        var += g[i] * d * d
    var /= gs
    w = min(max(math.sqrt(max(var, 0.0)), 0.3), 0.5 * (s[m - 1] - s[0])) if math.isfinite(var) else w0
    p[0], p[1], p[2], p[3], p[4] = lo, 0.0, hi - lo, c0, w


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _step_cost(y: np.ndarray, s: np.ndarray, p: np.ndarray) -> float:
    """Sum of squared residuals of a + b s + c Φ((s - s0)/w) (a reduction without stores: SIMD)."""
    a0, b0, c0, s0, iw = p[0], p[1], p[2], p[3], 1.0 / p[4]
    cost = 0.0
    for i in range(y.shape[0]):
        _, cdf = _phi_and_cdf((s[i] - s0) * iw)
        r = y[i] - (a0 + b0 * s[i] + c0 * cdf)
        cost += r * r
    return cost


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _step_normal_equations(y: np.ndarray, s: np.ndarray, p: np.ndarray, A: np.ndarray, gv: np.ndarray) -> None:
    """Jᵀ J (lower triangle) and Jᵀ r of the step model at p, J = [1, s, Φ, ∂/∂s0, ∂/∂w] per
    sample; accumulated in scalars in one pass without stores (SIMD)."""
    a0, b0, c0, s0, iw = p[0], p[1], p[2], p[3], 1.0 / p[4]
    k3 = -c0 * iw
    a10 = a11 = a20 = a21 = a22 = a30 = a31 = a32 = a33 = a40 = a41 = a42 = a43 = a44 = 0.0
    g0 = g1 = g2 = g3 = g4 = 0.0
    for i in range(y.shape[0]):
        j1 = s[i]
        z = (j1 - s0) * iw
        phi, j2 = _phi_and_cdf(z)
        ri = y[i] - (a0 + b0 * j1 + c0 * j2)
        j3 = k3 * phi
        j4 = j3 * z
        g0 += ri
        g1 += j1 * ri
        g2 += j2 * ri
        g3 += j3 * ri
        g4 += j4 * ri
        a10 += j1
        a11 += j1 * j1
        a20 += j2
        a21 += j2 * j1
        a22 += j2 * j2
        a30 += j3
        a31 += j3 * j1
        a32 += j3 * j2
        a33 += j3 * j3
        a40 += j4
        a41 += j4 * j1
        a42 += j4 * j2
        a43 += j4 * j3
        a44 += j4 * j4
    A[0, 0], A[1, 0], A[1, 1], A[2, 0], A[2, 1], A[2, 2] = float(y.shape[0]), a10, a11, a20, a21, a22
    A[3, 0], A[3, 1], A[3, 2], A[3, 3] = a30, a31, a32, a33
    A[4, 0], A[4, 1], A[4, 2], A[4, 3], A[4, 4] = a40, a41, a42, a43, a44
    gv[0], gv[1], gv[2], gv[3], gv[4] = g0, g1, g2, g3, g4


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _fit_step_row(y: np.ndarray, s: np.ndarray, w0: float, iterations: int, out: np.ndarray, ws: np.ndarray,
                  small: np.ndarray) -> None:
    """One profile's step fit into out[:4] = s0, w, c, RMS; ws (2, m) and small (4, 5, 5) are scratch."""
    A, L = small[0], small[1]
    p, pn, step, gv = small[3, 0], small[3, 1], small[3, 2], small[3, 3]
    _step_start(y, s, w0, p, ws[0], ws[1])
    cost = _step_cost(y, s, p)
    lam = 1e-2
    for _ in range(iterations):
        _step_normal_equations(y, s, p, A, gv)
        _damped_step(A, gv, lam, 5, L, step)
        for a in range(5):
            pn[a] = p[a] + step[a]
        pn[4] = min(max(pn[4], 0.15), 50.0)
        cn = _step_cost(y, s, pn)
        if cn < cost:
            p[:] = pn
            cost = cn
            lam *= 0.2
        else:
            lam *= 10.0
    out[0], out[1], out[2], out[3] = p[3], p[4], p[2], math.sqrt(cost / y.shape[0])


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def fit_step_rows(prof: np.ndarray, S: np.ndarray, w0: float, iterations: int) -> np.ndarray:
    """:func:`.edges.fit_step_profiles` of every row of ``prof`` (n, m) sampled at the rows of
    ``S`` (n, m): (n, 4) = s0, w, c, RMS residual."""
    n, m = prof.shape
    out = np.empty((n, 4))
    ws = np.empty((2, m))
    small = np.empty((4, 5, 5))
    for row in range(n):
        _fit_step_row(prof[row], S[row], w0, iterations, out[row], ws, small)
    return out


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _band_cost(y: np.ndarray, s: np.ndarray, p: np.ndarray) -> float:
    """Sum of squared residuals of a + b s - c [Φ((s - lo)/w_lo) - Φ((s - hi)/w_hi)] (SIMD)."""
    a0, b0, c0, lo, ilo, hi, ihi = p[0], p[1], p[2], p[3], 1.0 / p[4], p[5], 1.0 / p[6]
    cost = 0.0
    for i in range(y.shape[0]):
        _, cl = _phi_and_cdf((s[i] - lo) * ilo)
        _, ch = _phi_and_cdf((s[i] - hi) * ihi)
        r = y[i] - (a0 + b0 * s[i] - c0 * (cl - ch))
        cost += r * r
    return cost


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _band_normal_equations(y: np.ndarray, s: np.ndarray, p: np.ndarray, A: np.ndarray, gv: np.ndarray) -> None:
    """Jᵀ J (lower triangle) and Jᵀ r of the band model at p, J = [1, s, -band, ∂/∂lo, ∂/∂w_lo,
    ∂/∂hi, ∂/∂w_hi] per sample; in scalars, one pass without stores (SIMD)."""
    a0, b0, c0, lo, ilo, hi, ihi = p[0], p[1], p[2], p[3], 1.0 / p[4], p[5], 1.0 / p[6]
    k_lo, k_hi = c0 * ilo, -c0 * ihi
    a10 = a11 = a20 = a21 = a22 = a30 = a31 = a32 = a33 = a40 = a41 = a42 = a43 = a44 = 0.0
    a50 = a51 = a52 = a53 = a54 = a55 = a60 = a61 = a62 = a63 = a64 = a65 = a66 = 0.0
    g0 = g1 = g2 = g3 = g4 = g5 = g6 = 0.0
    for i in range(y.shape[0]):
        j1 = s[i]
        zl = (j1 - lo) * ilo
        zh = (j1 - hi) * ihi
        pl, cl = _phi_and_cdf(zl)
        ph, ch = _phi_and_cdf(zh)
        j2 = ch - cl  # -band
        ri = y[i] - (a0 + b0 * j1 + c0 * j2)
        j3 = k_lo * pl
        j4 = j3 * zl
        j5 = k_hi * ph
        j6 = j5 * zh
        g0 += ri
        g1 += j1 * ri
        g2 += j2 * ri
        g3 += j3 * ri
        g4 += j4 * ri
        g5 += j5 * ri
        g6 += j6 * ri
        a10 += j1
        a11 += j1 * j1
        a20 += j2
        a21 += j2 * j1
        a22 += j2 * j2
        a30 += j3
        a31 += j3 * j1
        a32 += j3 * j2
        a33 += j3 * j3
        a40 += j4
        a41 += j4 * j1
        a42 += j4 * j2
        a43 += j4 * j3
        a44 += j4 * j4
        a50 += j5
        a51 += j5 * j1
        a52 += j5 * j2
        a53 += j5 * j3
        a54 += j5 * j4
        a55 += j5 * j5
        a60 += j6
        a61 += j6 * j1
        a62 += j6 * j2
        a63 += j6 * j3
        a64 += j6 * j4
        a65 += j6 * j5
        a66 += j6 * j6
    A[0, 0], A[1, 0], A[1, 1], A[2, 0], A[2, 1], A[2, 2] = float(y.shape[0]), a10, a11, a20, a21, a22
    A[3, 0], A[3, 1], A[3, 2], A[3, 3] = a30, a31, a32, a33
    A[4, 0], A[4, 1], A[4, 2], A[4, 3], A[4, 4] = a40, a41, a42, a43, a44
    A[5, 0], A[5, 1], A[5, 2], A[5, 3], A[5, 4], A[5, 5] = a50, a51, a52, a53, a54, a55
    A[6, 0], A[6, 1], A[6, 2], A[6, 3], A[6, 4], A[6, 5], A[6, 6] = a60, a61, a62, a63, a64, a65, a66
    gv[0], gv[1], gv[2], gv[3], gv[4], gv[5], gv[6] = g0, g1, g2, g3, g4, g5, g6


@njit(cache=True, inline="always", fastmath=_FAST, error_model="numpy")
def _fit_band_row(y: np.ndarray, s: np.ndarray, start: np.ndarray, iterations: int, out: np.ndarray,
                  small: np.ndarray) -> None:
    """One profile's band fit from start = (lo0, hi0, w0) into out[:8]; small (4, 7, 7) is scratch."""
    m = y.shape[0]
    A, L = small[0], small[1]
    p, pn, step, gv = small[3, 0], small[3, 1], small[3, 2], small[3, 3]
    kk = max(2, m // 8)
    head = 0.0
    tail = 0.0
    for i in range(kk):
        head += y[i]
        tail += y[m - kk + i]
    level = (head / kk + tail / kk) / 2
    ymin = y[0]
    for i in range(m):
        ymin = min(ymin, y[i])
    p[0], p[1], p[2], p[3], p[4], p[5], p[6] = level, 0.0, level - ymin, start[0], start[2], start[1], start[2]
    cost = _band_cost(y, s, p)
    lam = 1e-2
    for _ in range(iterations):
        _band_normal_equations(y, s, p, A, gv)
        _damped_step(A, gv, lam, 7, L, step)
        for a in range(7):
            pn[a] = p[a] + step[a]
        pn[4] = min(max(pn[4], 0.15), 50.0)
        pn[6] = min(max(pn[6], 0.15), 50.0)
        cn = _band_cost(y, s, pn)
        if cn < cost:
            p[:] = pn
            cost = cn
            lam *= 0.2
        else:
            lam *= 10.0
    out[:7] = p
    out[7] = math.sqrt(cost / m)


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def fit_band_rows(prof: np.ndarray, S: np.ndarray, start: np.ndarray, iterations: int) -> np.ndarray:
    """:func:`.edges.fit_band_profiles` of every row from ``start`` (n, 3) = lo0, hi0, w0:
    (n, 8) = a, b, c, lo, w_lo, hi, w_hi and the RMS residual."""
    n = prof.shape[0]
    out = np.empty((n, 8))
    small = np.empty((4, 7, 7))
    for row in range(n):
        _fit_band_row(prof[row], S[row], start[row], iterations, out[row], small)
    return out


def compile_all() -> float:
    """Compile every kernel the detection uses (or load it from numba's cache), so that the first
    frame does not pay for it: about 10 s of CPU on a cold cache, 0.5 s from the cache. Returns
    the seconds it took (``python -m pascal_calib_ros.detect.edge_kernels``; ``make venv`` runs it)."""
    import time

    from ..geometry import conic_kernels

    t = time.perf_counter()
    prof = np.linspace(0.0, 1.0, 26).reshape(2, 13)
    S = np.ascontiguousarray(np.broadcast_to(np.linspace(-3.0, 3.0, 13), (2, 13)))
    fit_step_rows(prof, S, 1.0, 1)
    fit_band_rows(prof, S, np.ones((2, 3)), 1)
    pts = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [0.7, 0.7], [-0.7, 0.7]])
    conic_kernels.refine_ellipse(np.array([0.0, 0.0, 1.0, 1.0, 0.0]), pts, 1)
    conic_kernels.group_conic_moments(pts, np.zeros(len(pts), np.int64), 1)
    return time.perf_counter() - t


if __name__ == "__main__":
    print(f"detection kernels compiled or loaded from numba's cache in {compile_all():.1f} s")
