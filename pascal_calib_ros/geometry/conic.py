"""Conics: fitting, normalisation, ellipse parameters, sampling.

A conic is a symmetric 3x3 matrix C with x^T C x = 0 for homogeneous points x = (u, v, 1):
a u^2 + b u v + c v^2 + d u + e v + f = 0  <->  C = [[a, b/2, d/2], [b/2, c, e/2], [d/2, e/2, f]].
Conics are defined up to scale and sign; :func:`normalize_conic` fixes both (unit Frobenius norm,
positive trace of the upper-left 2x2 block, so the inside of an ellipse is negative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class ConicFitError(ValueError):
    """The points do not determine an ellipse."""


def normalize_conic(C: np.ndarray) -> np.ndarray:
    """Unit Frobenius norm and positive trace of the 2x2 block (PAPER.md, pitfalls)."""
    C = np.asarray(C, float)
    C = (C + C.T) / 2
    n = np.linalg.norm(C)
    if n == 0:
        raise ConicFitError("zero conic")
    C = C / n
    if C[0, 0] + C[1, 1] < 0:
        C = -C
    return C


def conic_from_coeffs(a: float, b: float, c: float, d: float, e: float, f: float) -> np.ndarray:
    return np.array([[a, b / 2, d / 2], [b / 2, c, e / 2], [d / 2, e / 2, f]], float)


def _norm_transform(pts: np.ndarray) -> np.ndarray:
    """Hartley normalisation: centroid to origin, mean distance sqrt(2)."""
    m = pts.mean(axis=0)
    s = np.sqrt(2) / max(np.mean(np.linalg.norm(pts - m, axis=1)), 1e-12)
    return np.array([[s, 0, -s * m[0]], [0, s, -s * m[1]], [0, 0, 1]])


def fit_conic_algebraic(pts: np.ndarray) -> np.ndarray:
    """Ellipse-specific direct least squares (Fitzgibbon, Pilu, Fisher 1999; Halir-Flusser form)
    on Hartley-normalised points. Returns the normalised conic in the input coordinates."""
    pts = np.asarray(pts, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 5:
        raise ConicFitError(f"need at least 5 points (N, 2) to fit a conic, got {pts.shape}")
    sv = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if sv[1] < 1e-9 * max(sv[0], 1e-300):
        raise ConicFitError("points are degenerate (collinear or repeated)")
    T = _norm_transform(pts)
    p = pts @ T[:2, :2].T + T[:2, 2]
    x, y = p[:, 0], p[:, 1]
    D1 = np.stack([x * x, x * y, y * y], 1)
    D2 = np.stack([x, y, np.ones_like(x)], 1)
    S1, S2, S3 = D1.T @ D1, D1.T @ D2, D2.T @ D2
    try:
        Tm = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError:
        raise ConicFitError("points are degenerate (collinear or repeated)") from None
    M = S1 + S2 @ Tm
    M = np.array([M[2] / 2, -M[1], M[0] / 2])
    _w, v = np.linalg.eig(M)
    v = np.real(v)
    cond = 4 * v[0] * v[2] - v[1] ** 2
    ok = np.nonzero(cond > 0)[0]
    if len(ok) == 0:
        raise ConicFitError("points do not lie on an ellipse")
    a1 = v[:, ok[0]]
    coef = np.concatenate([a1, Tm @ a1])
    Cn = conic_from_coeffs(*coef)
    return normalize_conic(T.T @ Cn @ T)


def sampson_distance(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """First-order geometric (Sampson) distance of points to a conic, signed (negative inside)."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    CX = X @ C
    alg = np.sum(CX * X, axis=1)
    grad = 2 * CX[:, :2]
    return alg / np.maximum(np.linalg.norm(grad, axis=1), 1e-300)


def fit_conic(pts: np.ndarray, refine: bool = True, iterations: int = 10) -> np.ndarray:
    """Algebraic ellipse fit, then geometric refinement (Gauss-Newton on the Sampson distance
    over the ellipse's 5 parameters). Returns a normalised conic."""
    C = fit_conic_algebraic(pts)
    if not refine:
        return C
    try:
        e = Ellipse.from_conic(C)
    except ConicFitError:
        return C
    params = np.array([e.cx, e.cy, e.a, e.b, e.angle])
    scale = max(e.a, 1e-9)
    prev = np.inf
    for _ in range(iterations):
        r = _ellipse_residual(params, pts)
        cost = float(r @ r)
        J = np.empty((len(pts), 5))
        for k in range(5):
            h = 1e-6 * (scale if k < 4 else 1.0)
            dp = params.copy()
            dp[k] += h
            J[:, k] = (_ellipse_residual(dp, pts) - r) / h
        try:
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
        except np.linalg.LinAlgError:
            break
        new = params + step
        if new[2] <= 0 or new[3] <= 0:
            break
        if float(np.sum(_ellipse_residual(new, pts) ** 2)) > cost:
            break
        params = new
        if prev - cost < 1e-14 * max(cost, 1e-30):
            break
        prev = cost
    return Ellipse(*params).to_conic()


def _ellipse_residual(p: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return sampson_distance(Ellipse(*p).to_conic(), pts)


@dataclass(frozen=True)
class Ellipse:
    """Centre, semi-axes a >= b (not enforced), rotation of the a-axis (radians)."""

    cx: float
    cy: float
    a: float
    b: float
    angle: float

    def to_conic(self) -> np.ndarray:
        c, s = np.cos(self.angle), np.sin(self.angle)
        R = np.array([[c, -s], [s, c]])
        A = R @ np.diag([1 / self.a**2, 1 / self.b**2]) @ R.T
        ctr = np.array([self.cx, self.cy])
        C = np.zeros((3, 3))
        C[:2, :2] = A
        C[:2, 2] = C[2, :2] = -A @ ctr
        C[2, 2] = ctr @ A @ ctr - 1
        return normalize_conic(C)

    @staticmethod
    def from_conic(C: np.ndarray) -> Ellipse:
        C = normalize_conic(C)
        A = C[:2, :2]
        w = np.linalg.eigvalsh(A)
        if w[0] <= 0:
            raise ConicFitError("conic is not an ellipse")
        ctr = -np.linalg.solve(A, C[:2, 2])
        k = -(C[2, 2] + C[:2, 2] @ ctr)
        if k <= 0:
            raise ConicFitError("conic is an imaginary ellipse")
        w, v = np.linalg.eigh(A / k)
        a, b = 1 / np.sqrt(w[0]), 1 / np.sqrt(w[1])
        ang = float(np.arctan2(v[1, 0], v[0, 0]))
        return Ellipse(float(ctr[0]), float(ctr[1]), float(a), float(b), ang)

    def sample(self, n: int, phase: float = 0.0) -> np.ndarray:
        """n points (n, 2) equally spaced in the parametric angle."""
        t = phase + np.linspace(0, 2 * np.pi, n, endpoint=False)
        c, s = np.cos(self.angle), np.sin(self.angle)
        x, y = self.a * np.cos(t), self.b * np.sin(t)
        return np.stack([self.cx + c * x - s * y, self.cy + s * x + c * y], 1)

    @property
    def perimeter(self) -> float:
        a, b = self.a, self.b
        h = ((a - b) / (a + b)) ** 2
        return float(np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h))))


def conic_normals(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Unit outward normals (gradient direction of x^T C x) at points (N, 2)."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    g = (X @ C)[:, :2]
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def conic_curvature(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Curvature (1/px) of the conic at points lying on it: |grad^T adj-Hessian| formula
    k = |f_xx f_y^2 - 2 f_xy f_x f_y + f_yy f_x^2| / |grad f|^3 for f(x, y) = x^T C x."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    g = 2 * (X @ C)[:, :2]
    fx, fy = g[:, 0], g[:, 1]
    fxx, fxy, fyy = 2 * C[0, 0], 2 * C[0, 1], 2 * C[1, 1]
    num = np.abs(fxx * fy**2 - 2 * fxy * fx * fy + fyy * fx**2)
    return num / np.maximum(np.hypot(fx, fy) ** 3, 1e-300)


def conic_image_of_circle(H: np.ndarray, center: tuple[float, float], radius: float) -> np.ndarray:
    """Image conic of a circle on a plane mapped to the image by homography H: C' = H^-T C H^-1."""
    cx, cy = center
    C = np.array([[1, 0, -cx], [0, 1, -cy], [-cx, -cy, cx * cx + cy * cy - radius * radius]], float)
    Hi = np.linalg.inv(H)
    return normalize_conic(Hi.T @ C @ Hi)


def line_conic_intersection(line: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two (possibly complex) intersections of a line with a conic, homogeneous 3-vectors.

    Points on the line are p(t) = u + t v with u, v a real basis of the line's null space; then
    p^T C p = 0 is a quadratic in t."""
    line = np.asarray(line, float)
    # basis of {p : line . p = 0}
    _, _, vt = np.linalg.svd(line.reshape(1, 3))
    u, v = vt[1], vt[2]
    a = v @ C @ v
    b = 2 * (u @ C @ v)
    c = u @ C @ u
    disc = complex(b * b - 4 * a * c)
    sq = np.sqrt(disc)
    t1 = (-b + sq) / (2 * a)
    t2 = (-b - sq) / (2 * a)
    return u + t1 * v, u + t2 * v
