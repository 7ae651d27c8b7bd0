"""Compiled kernels of the refinement's edge rows (numba) for a flat target seen through a
polynomial lens (``plumb_bob``, ``rational_polynomial``): :meth:`.problem.Problem._edge_fit`'s foot
points and residuals, and :meth:`.problem.Problem._edge_jacobian`'s rows, one pass over the points
instead of some hundred numpy passes over arrays of tens of thousands of points.

The arithmetic is the numpy path's, point by point, in the same order of operations where it
matters (the foot point's one Gauss-Newton step on the angle, the outward normal's orientation);
the numpy path stays the reference (``test/calibrate/solver/test_edge_row_kernels.py`` compares them) and
serves the warped target and the fisheye model. Formulas: :mod:`.problem` and :mod:`..geometry.lens`
(OpenCV's rational radial factor R = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)).

This module imports numba; :mod:`.problem` imports it on first use, numba compiles each kernel on
its first call and caches the machine code on disk (``cache=True``). ``error_model="numpy"``: a
division by zero gives inf or NaN as numpy's does (the caller replaces non-finite residuals).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def _distort(X: float, Y: float, Z: float, D: np.ndarray) -> tuple[float, float, float, float, float, float, float,
                                                                    float, float, float, float]:
    """x_d, y_d of a camera-frame point and what the Jacobians need: x, y, r^2, den, R, and
    d x_d / d (x, y) as a, b, c, d, and 1 / Z."""
    iz = 1.0 / Z
    x, y = X * iz, Y * iz
    k1, k2, p1, p2, k3, k4, k5, k6 = D[0], D[1], D[2], D[3], D[4], D[5], D[6], D[7]
    r2 = x * x + y * y
    num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
    dradial = ((k1 + r2 * (2 * k2 + 3 * k3 * r2)) * den - num * (k4 + r2 * (2 * k5 + 3 * k6 * r2))) / (den * den)
    radial = num / den
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    b = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    a = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
    d = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
    return xd, yd, x, y, r2, den, radial, a, b, d, iz


@njit(cache=True, error_model="numpy", inline="always")
def _project(X: float, Y: float, Z: float, K: np.ndarray, D: np.ndarray, J: np.ndarray) -> tuple[float, float]:
    """The pixel of a camera-frame point; dq/dX (2, 3) into ``J``. K = (fx, fy, cx, cy, skew)."""
    xd, yd, x, y, _, _, _, a, b, d, iz = _distort(X, Y, Z, D)
    c = b
    mx, my = -x * iz, -y * iz
    j00, j01, j02 = a * iz, b * iz, a * mx + b * my
    j10, j11, j12 = c * iz, d * iz, c * mx + d * my
    fx, fy, cx, cy, s = K[0], K[1], K[2], K[3], K[4]
    if s != 0.0:
        J[0, 0], J[0, 1], J[0, 2] = fx * j00 + s * j10, fx * j01 + s * j11, fx * j02 + s * j12
        u = fx * xd + s * yd + cx
    else:
        J[0, 0], J[0, 1], J[0, 2] = fx * j00, fx * j01, fx * j02
        u = fx * xd + cx
    J[1, 0], J[1, 1], J[1, 2] = fy * j10, fy * j11, fy * j12
    return u, fy * yd + cy


@njit(cache=True, error_model="numpy")
def edge_rays(pts: np.ndarray, K: np.ndarray, D: np.ndarray, start: np.ndarray, rays: np.ndarray) -> None:
    """Unit rays of pixels (:meth:`..geometry.lens.PolynomialModel.undistort` without ``strict``):
    the affine part of K inverted, then Newton's method on the distortion from x = x_d (or from
    ``start`` (N, 3), the rays of a nearby camera, when it has N rows), at most 8 steps, each point
    until its step is below 1e-13 (1 + |x|) (numpy: until every point's is)."""
    fx, fy, cx, cy, s = K[0], K[1], K[2], K[3], K[4]
    distorted = False
    for k in range(8):
        distorted = distorted or D[k] != 0.0
    warm = start.shape[0] == pts.shape[0]
    for i in range(pts.shape[0]):
        yd = (pts[i, 1] - cy) / fy
        xd = (pts[i, 0] - cx - s * yd) / fx
        x, y = xd, yd
        if distorted and warm and start[i, 2] > 0:
            x, y = start[i, 0] / start[i, 2], start[i, 1] / start[i, 2]
        if distorted:
            for _ in range(8):
                ex, ey, _, _, _, _, _, a, b, d, _ = _distort(x, y, 1.0, D)
                c = b
                det = a * d - b * c
                if abs(det) < 1e-12:
                    det = 1e-12
                fx_, fy_ = ex - xd, ey - yd
                dx = (d * fx_ - b * fy_) / det
                dy = (-c * fx_ + a * fy_) / det
                x -= dx
                y -= dy
                if abs(dx) + abs(dy) < 1e-13 * (1.0 + max(abs(x), abs(y))):
                    break
        nrm = math.sqrt(x * x + y * y + 1.0)
        rays[i, 0], rays[i, 1], rays[i, 2] = x / nrm, y / nrm, 1.0 / nrm


@njit(cache=True, error_model="numpy")
def edge_fit(pts: np.ndarray, rays: np.ndarray, vi: np.ndarray, centers: np.ndarray, radii: np.ndarray,
             signs: np.ndarray, offsets: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, D: np.ndarray,
             f: np.ndarray, nrm: np.ndarray, Q: np.ndarray, Xc: np.ndarray, dqdX: np.ndarray) -> None:
    """The edge rows of a flat target (:meth:`.problem.Problem._edge_fit`): per point its ray
    ``rays[i]`` met with the plane of view ``vi[i]`` (R (V, 3, 3), t (V, 3)), the circle point Q
    in that direction from the centre, slid along the circle by one Gauss-Newton step on the angle
    to the image foot point, the residual f = n . (u - q) - sign offset, the outward normal n,
    Q, its camera-frame point Xc and dq/dX there. D: the 8 rational coefficients."""
    J = np.empty((2, 3))
    for i in range(pts.shape[0]):
        v = vi[i]
        r0, r1, r2_ = rays[i, 0], rays[i, 1], rays[i, 2]
        nz = R[v, 0, 2] * t[v, 0] + R[v, 1, 2] * t[v, 1] + R[v, 2, 2] * t[v, 2]
        lam = nz / (r0 * R[v, 0, 2] + r1 * R[v, 1, 2] + r2_ * R[v, 2, 2])
        e0, e1, e2 = r0 * lam - t[v, 0], r1 * lam - t[v, 1], r2_ * lam - t[v, 2]
        rel0 = e0 * R[v, 0, 0] + e1 * R[v, 1, 0] + e2 * R[v, 2, 0] - centers[i, 0]
        rel1 = e0 * R[v, 0, 1] + e1 * R[v, 1, 1] + e2 * R[v, 2, 1] - centers[i, 1]
        rho = max(math.hypot(rel0, rel1), 1e-12)
        u0, u1 = rel0 / rho, rel1 / rho
        r = radii[i]
        q0 = q1 = ti0 = ti1 = 0.0
        X0 = X1 = X2 = 0.0
        Q0 = Q1 = 0.0
        for step in range(2):
            Q0, Q1 = centers[i, 0] + r * u0, centers[i, 1] + r * u1
            X0 = R[v, 0, 0] * Q0 + R[v, 0, 1] * Q1 + t[v, 0]
            X1 = R[v, 1, 0] * Q0 + R[v, 1, 1] * Q1 + t[v, 1]
            X2 = R[v, 2, 0] * Q0 + R[v, 2, 1] * Q1 + t[v, 2]
            q0, q1 = _project(X0, X1, X2, K, D, J)
            # the image of the circle's tangent (-u1, u0) (per radian / r)
            g0 = R[v, 0, 0] * -u1 + R[v, 0, 1] * u0
            g1 = R[v, 1, 0] * -u1 + R[v, 1, 1] * u0
            g2 = R[v, 2, 0] * -u1 + R[v, 2, 1] * u0
            ti0 = J[0, 0] * g0 + J[0, 1] * g1 + J[0, 2] * g2
            ti1 = J[1, 0] * g0 + J[1, 1] * g1 + J[1, 2] * g2
            if step:
                break
            dq0, dq1 = ti0 * r, ti1 * r
            d0, d1 = pts[i, 0] - q0, pts[i, 1] - q1
            dth = (dq0 * d0 + dq1 * d1) / max(dq0 * dq0 + dq1 * dq1, 1e-30)
            c, s_ = math.cos(dth), math.sin(dth)
            u0, u1 = c * u0 - s_ * u1, s_ * u0 + c * u1
        # the image of the outward radius u
        g0 = R[v, 0, 0] * u0 + R[v, 0, 1] * u1
        g1 = R[v, 1, 0] * u0 + R[v, 1, 1] * u1
        g2 = R[v, 2, 0] * u0 + R[v, 2, 1] * u1
        ri0 = J[0, 0] * g0 + J[0, 1] * g1 + J[0, 2] * g2
        ri1 = J[1, 0] * g0 + J[1, 1] * g1 + J[1, 2] * g2
        tn = max(math.hypot(ti0, ti1), 1e-15)
        ti0, ti1 = ti0 / tn, ti1 / tn
        cross = ri0 * ti1 - ri1 * ti0
        orient = 1.0 if cross > 0 else (-1.0 if cross < 0 else (0.0 if cross == 0 else cross))
        n0, n1 = ti1 * orient, -ti0 * orient
        nrm[i, 0], nrm[i, 1] = n0, n1
        f[i] = (n0 * (pts[i, 0] - q0) + n1 * (pts[i, 1] - q1)) - signs[i] * offsets[v]
        Q[i, 0], Q[i, 1] = Q0, Q1
        Xc[i, 0], Xc[i, 1], Xc[i, 2] = X0, X1, X2
        for a in range(2):
            for b in range(3):
                dqdX[i, a, b] = J[a, b]


@njit(cache=True, error_model="numpy")
def edge_jacobian(nrm: np.ndarray, Q: np.ndarray, Xc: np.ndarray, dqdX: np.ndarray, vi: np.ndarray,
                  signs: np.ndarray, K: np.ndarray, D: np.ndarray, n_coef: int, free: np.ndarray, dR: np.ndarray,
                  use_offsets: bool, Jg: np.ndarray, Jv: np.ndarray) -> None:
    """The edge rows' Jacobian (:meth:`.problem.Problem._edge_jacobian`) of a flat target: -n^T
    dq/d theta at the foot point; ``Jg[:, :len(free)]`` over the free intrinsics (indices into
    (fx, fy, cx, cy, skew, D[:n_coef])), ``Jv`` over the view's rotation (dR (V, nr, 3, 3)),
    translation and (``use_offsets``) edge offset."""
    fx, fy, s = K[0], K[1], K[4]
    nr = dR.shape[1]
    nf = free.shape[0]
    dI0 = np.zeros(5 + n_coef)
    dI1 = np.zeros(5 + n_coef)
    for i in range(nrm.shape[0]):
        v = vi[i]
        n0, n1 = nrm[i, 0], nrm[i, 1]
        h0 = n0 * dqdX[i, 0, 0] + n1 * dqdX[i, 1, 0]
        h1 = n0 * dqdX[i, 0, 1] + n1 * dqdX[i, 1, 1]
        h2 = n0 * dqdX[i, 0, 2] + n1 * dqdX[i, 1, 2]
        if nf:
            xd, yd, x, y, r2, den, radial, _, _, _, _ = _distort(Xc[i, 0], Xc[i, 1], Xc[i, 2], D)
            r4, r6 = r2 * r2, r2 * r2 * r2
            xs, ys = x / den, y / den
            # d x_d / d D (rows 0, 1), then the affine part of K
            c00, c01, c04 = xs * r2, xs * r4, xs * r6
            c10, c11, c14 = ys * r2, ys * r4, ys * r6
            c02 = c13 = 2 * x * y
            c03 = r2 + 2 * x * x
            c12 = r2 + 2 * y * y
            dI0[0], dI0[1], dI0[2], dI0[3], dI0[4] = xd, 0.0, 1.0, 0.0, yd
            dI1[0], dI1[1], dI1[2], dI1[3], dI1[4] = 0.0, yd, 0.0, 1.0, 0.0
            row0 = (c00, c01, c02, c03, c04)
            row1 = (c10, c11, c12, c13, c14)
            for k in range(5):
                dI0[5 + k] = fx * row0[k] + s * row1[k] if s != 0.0 else fx * row0[k]
                dI1[5 + k] = fy * row1[k]
            if n_coef == 8:
                for k in range(3):
                    rk = r2 if k == 0 else (r4 if k == 1 else r6)
                    a0, a1 = -xs * radial * rk, -ys * radial * rk
                    dI0[10 + k] = fx * a0 + s * a1 if s != 0.0 else fx * a0
                    dI1[10 + k] = fy * a1
            for k in range(nf):
                Jg[i, k] = -(n0 * dI0[free[k]] + n1 * dI1[free[k]])
        q0, q1 = Q[i, 0], Q[i, 1]
        for k in range(nr):
            acc = 0.0
            acc += h0 * dR[v, k, 0, 0] * q0 + h0 * dR[v, k, 0, 1] * q1
            acc += h1 * dR[v, k, 1, 0] * q0 + h1 * dR[v, k, 1, 1] * q1
            acc += h2 * dR[v, k, 2, 0] * q0 + h2 * dR[v, k, 2, 1] * q1
            Jv[i, k] = -acc
        Jv[i, nr], Jv[i, nr + 1], Jv[i, nr + 2] = -h0, -h1, -h2
        if use_offsets:
            Jv[i, nr + 3] = -signs[i]


def compile_all() -> float:
    """Compile the kernels (or load them from numba's cache) on a tiny problem; seconds taken."""
    import time

    t0 = time.perf_counter()
    n = 2
    pts, rays = np.zeros((n, 2)), np.tile([0.0, 0.0, 1.0], (n, 1))
    vi = np.zeros(n, np.int64)
    R, t = np.eye(3)[None].copy(), np.array([[0.0, 0.0, 1.0]])
    K, D = np.array([500.0, 500.0, 320.0, 240.0, 0.0]), np.zeros(8)
    f, nrm, Q, Xc, dqdX = np.empty(n), np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 3)), np.empty((n, 2, 3))
    edge_rays(pts, K, D, np.zeros((0, 3)), rays)
    edge_fit(pts=pts, rays=rays, vi=vi, centers=np.zeros((n, 2)), radii=np.full(n, 0.01), signs=np.ones(n),
             offsets=np.zeros(1), R=R, t=t, K=K, D=D, f=f, nrm=nrm, Q=Q, Xc=Xc, dqdX=dqdX)
    edge_jacobian(nrm=nrm, Q=Q, Xc=Xc, dqdX=dqdX, vi=vi, signs=np.ones(n), K=K, D=D, n_coef=5,
                  free=np.arange(9, dtype=np.int64), dR=np.zeros((1, 3, 3, 3)), use_offsets=True,
                  Jg=np.empty((n, 9)), Jv=np.empty((n, 7)))
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"refinement kernels compiled or loaded from numba's cache in {compile_all():.1f} s")
