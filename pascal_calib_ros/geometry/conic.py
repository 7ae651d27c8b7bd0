"""Conics: fitting, normalisation, ellipse parameters, sampling.

A conic is a symmetric 3x3 matrix C with x^T C x = 0 for homogeneous points x = (u, v, 1):
a u^2 + b u v + c v^2 + d u + e v + f = 0  <->  C = [[a, b/2, d/2], [b/2, c, e/2], [d/2, e/2, f]].
Conics are defined up to scale and sign; :func:`normalize_conic` fixes both (unit Frobenius norm,
positive trace of the upper-left 2x2 block, so the inside of an ellipse is negative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PascalCalibError


class ConicFitError(PascalCalibError):
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


def group_medians(values: np.ndarray, owner: np.ndarray, n_groups: int) -> np.ndarray:
    """Median of ``values`` within each group (owner: group of each value; empty groups: nan)."""
    lo_v, hi_v = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
    key = owner + 0.999 * (values - lo_v) / max(hi_v - lo_v, 1e-300)  # group, then value: one float sort
    v = np.append(values[np.argsort(key, kind="stable")], np.nan)
    counts = np.bincount(owner, minlength=n_groups)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    lo = np.where(counts > 0, starts + (counts - 1) // 2, len(values))
    hi = np.where(counts > 0, starts + counts // 2, len(values))
    return (v[lo] + v[hi]) / 2


def fit_conics_algebraic(pts: np.ndarray, owner: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fit_conic_algebraic` for many point sets at once (rows of ``pts`` grouped by
    ``owner``, sorted): conics (G, 3, 3) and a mask of groups that gave an ellipse (the others,
    empty groups and groups of fewer than 5 points included, hold zeros)."""
    from . import conic_kernels

    counts, mean, scale, S = conic_kernels.group_conic_moments(np.require(pts, np.float64, ["C", "W"]),
                                                               np.require(owner, np.int64, ["C", "W"]), int(n_groups))
    S1, S2, S3 = S[:, :3, :3], S[:, :3, 3:], S[:, 3:, 3:]  # Σ D1ᵀD1, D1ᵀD2, D2ᵀD2 per group
    ok = counts >= 5
    ok &= np.abs(np.linalg.det(S3)) > 1e-12 * np.maximum(np.abs(S3).max(axis=(1, 2)) ** 3, 1e-300)
    S3 = np.where(ok[:, None, None], S3, np.eye(3))
    Tm = -np.linalg.solve(S3, np.transpose(S2, (0, 2, 1)))
    M = S1 + S2 @ Tm
    M = np.stack([M[:, 2] / 2, -M[:, 1], M[:, 0] / 2], 1)
    M = np.where(np.isfinite(M).all(axis=(1, 2))[:, None, None], M, np.eye(3))
    _w, v = np.linalg.eig(M)
    v = np.real(v)
    cond = 4 * v[:, 0] * v[:, 2] - v[:, 1] ** 2  # (G, 3): one per eigenvector
    pick = np.argmax(cond > 0, axis=1)
    ok &= (cond > 0).any(axis=1)
    a1 = v[np.arange(n_groups), :, pick]  # (G, 3)
    a2 = np.einsum("gij,gj->gi", Tm, a1)
    a, b, c = a1[:, 0], a1[:, 1], a1[:, 2]
    d, e, f = a2[:, 0], a2[:, 1], a2[:, 2]
    Cn = np.stack([np.stack([a, b / 2, d / 2], -1), np.stack([b / 2, c, e / 2], -1),
                   np.stack([d / 2, e / 2, f], -1)], 1)
    T = np.zeros((n_groups, 3, 3))
    T[:, 0, 0] = T[:, 1, 1] = scale
    T[:, :2, 2] = -scale[:, None] * mean
    T[:, 2, 2] = 1.0
    C = np.transpose(T, (0, 2, 1)) @ Cn @ T
    C = (C + np.transpose(C, (0, 2, 1))) / 2
    norm = np.linalg.norm(C, axis=(1, 2))
    ok &= norm > 0
    C = C / np.where(norm > 0, norm, 1.0)[:, None, None]
    C *= np.where(C[:, 0, 0] + C[:, 1, 1] < 0, -1.0, 1.0)[:, None, None]
    ok &= np.isfinite(C).all(axis=(1, 2))
    return np.where(ok[:, None, None], C, 0.0), ok


def sampson_distances(C: np.ndarray, pts: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """:func:`sampson_distance` of each point to its own group's conic C[owner]."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    CX = np.einsum("nj,njk->nk", X, C[owner])
    alg = np.sum(CX * X, axis=1)
    return alg / np.maximum(2 * np.linalg.norm(CX[:, :2], axis=1), 1e-300)


def ellipses_from_conics(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Ellipse.from_conic` for (G, 3, 3) conics (G may be 0): parameters (G, 5) =
    (cx, cy, a, b, angle) and a mask of real ellipses."""
    C = np.asarray(C, float).reshape(-1, 3, 3)
    C = C / np.maximum(np.linalg.norm(C, axis=(1, 2)), 1e-300)[:, None, None]
    C = C * np.where(C[:, 0, 0] + C[:, 1, 1] < 0, -1.0, 1.0)[:, None, None]
    A = C[:, :2, :2]
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] ** 2
    ok = (det > 0) & (A[:, 0, 0] > 0)
    A_safe = np.where(ok[:, None, None], A, np.eye(2))
    ctr = -np.linalg.solve(A_safe, C[:, :2, 2:3])[:, :, 0]
    k = -(C[:, 2, 2] + np.einsum("gi,gi->g", C[:, :2, 2], ctr))
    ok &= k > 0
    w, v = np.linalg.eigh(A_safe / np.where(k > 0, k, 1.0)[:, None, None])
    w = np.where(ok[:, None], w, 1.0)
    out = np.stack([ctr[:, 0], ctr[:, 1], 1 / np.sqrt(w[:, 0]), 1 / np.sqrt(w[:, 1]),
                    np.arctan2(v[:, 1, 0], v[:, 0, 0])], 1)
    return out, ok


def conics_from_ellipses(par: np.ndarray) -> np.ndarray:
    """:meth:`Ellipse.to_conic` for (G, 5) ellipses (cx, cy, a, b, angle) at once: (G, 3, 3)
    normalised conics."""
    par = np.asarray(par, float).reshape(-1, 5)
    cx, cy, a, b, ang = par.T
    c, s = np.cos(ang), np.sin(ang)
    ia, ib = 1 / a**2, 1 / b**2
    A = np.empty((len(par), 2, 2))
    A[:, 0, 0] = c * c * ia + s * s * ib
    A[:, 0, 1] = A[:, 1, 0] = c * s * (ia - ib)
    A[:, 1, 1] = s * s * ia + c * c * ib
    ctr = np.stack([cx, cy], 1)
    Ac = np.einsum("gij,gj->gi", A, ctr)
    C = np.zeros((len(par), 3, 3))
    C[:, :2, :2] = A
    C[:, :2, 2] = C[:, 2, :2] = -Ac
    C[:, 2, 2] = np.einsum("gi,gi->g", ctr, Ac) - 1
    C /= np.linalg.norm(C, axis=(1, 2))[:, None, None]
    return C * np.where(C[:, 0, 0] + C[:, 1, 1] < 0, -1.0, 1.0)[:, None, None]


def sampson_distance(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """First-order geometric (Sampson) distance of points to a conic, signed (negative inside)."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    CX = X @ C
    alg = np.sum(CX * X, axis=1)
    grad = 2 * CX[:, :2]
    return alg / np.maximum(np.linalg.norm(grad, axis=1), 1e-300)


def fit_conic(pts: np.ndarray, refine: bool = True, iterations: int = 10) -> np.ndarray:
    """Algebraic ellipse fit, then geometric refinement (Gauss-Newton on the Sampson distance
    over the ellipse's 5 parameters, compiled: :func:`.conic_kernels.refine_ellipse`). Returns a
    normalised conic."""
    C = fit_conic_algebraic(pts)
    if not refine:
        return C
    try:
        e = Ellipse.from_conic(C)
    except ConicFitError:
        return C
    from . import conic_kernels

    start = np.array([e.cx, e.cy, e.a, e.b, e.angle])
    params = conic_kernels.refine_ellipse(start, np.require(pts, np.float64, ["C", "W"]), int(iterations))
    return Ellipse(*(float(v) for v in params)).to_conic()


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
        return float(ellipse_perimeter(self.a, self.b))


def ellipse_perimeter(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """Ramanujan's second approximation of an ellipse's perimeter (elementwise)."""
    h = ((np.asarray(a) - b) / (np.asarray(a) + b)) ** 2
    return np.pi * (np.asarray(a) + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))


def conic_normals(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Unit outward normals (gradient direction of x^T C x) at points (N, 2)."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    g = (X @ C)[:, :2]
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def conic_curvature(C: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Curvature (1/px) of the conic at points lying on it: |grad^T adj-Hessian| formula
    k = |f_xx f_y^2 - 2 f_xy f_x f_y + f_yy f_x^2| / |grad f|^3 for f(x, y) = x^T C x.
    C is one conic (3, 3) or one per point (N, 3, 3)."""
    X = np.concatenate([pts, np.ones((len(pts), 1))], 1)
    g = 2 * (np.einsum("nj,njk->nk", X, C) if C.ndim == 3 else X @ C)[:, :2]
    fx, fy = g[:, 0], g[:, 1]
    fxx, fxy, fyy = 2 * C[..., 0, 0], 2 * C[..., 0, 1], 2 * C[..., 1, 1]
    num = np.abs(fxx * fy**2 - 2 * fxy * fx * fy + fyy * fx**2)
    return num / np.maximum(np.hypot(fx, fy) ** 3, 1e-300)


def conic_image_of_circle(H: np.ndarray, center: tuple[float, float], radius: float) -> np.ndarray:
    """Image conic of a circle on a plane mapped to the image by homography H: C' = H^-T C H^-1."""
    cx, cy = center
    C = np.array([[1, 0, -cx], [0, 1, -cy], [-cx, -cy, cx * cx + cy * cy - radius * radius]], float)
    Hi = np.linalg.inv(H)
    return normalize_conic(Hi.T @ C @ Hi)


def ray_conic_nearest(C: np.ndarray, P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Per row, the offset s of the intersection of the ray P + s N with the conic C (one (3, 3)
    per row) nearest to P; NaN where the line misses it."""
    nx, ny, px, py = N[:, 0], N[:, 1], P[:, 0], P[:, 1]
    c00, c01, c02, c11, c12, c22 = C[:, 0, 0], C[:, 0, 1], C[:, 0, 2], C[:, 1, 1], C[:, 1, 2], C[:, 2, 2]
    gx, gy = c00 * px + c01 * py + c02, c01 * px + c11 * py + c12  # (C X)[:2] for a symmetric C
    qa = c00 * nx * nx + 2 * c01 * nx * ny + c11 * ny * ny  # dᵀ C d, d = (N, 0)
    qb = nx * gx + ny * gy  # dᵀ C X
    qc = px * gx + py * gy + (c02 * px + c12 * py + c22)  # Xᵀ C X
    disc = qb * qb - qa * qc
    sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1, r2 = (-qb + sq) / qa, (-qb - sq) / qa
    return np.where(np.abs(r1) < np.abs(r2), r1, r2)


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
    sq = np.sqrt(complex(b * b - 4 * a * c))
    # the root formula without cancellation (Press et al., Numerical Recipes, section 5.6):
    # q = -(b + sign sq) / 2 with the sign that adds magnitudes; t1 = q / a, t2 = c / q
    if (b.conjugate() * sq).real < 0:
        sq = -sq
    q = -0.5 * (b + sq)
    if q == 0:  # b = 0 and c = 0: a double root at t = 0
        return u.astype(complex), u.astype(complex)
    t1, t2 = q / a, c / q
    return u + t1 * v, u + t2 * v
