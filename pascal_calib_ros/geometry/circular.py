"""Images of the circular points i', j' of a target plane, from image conics of its circles.

The circular points I, J = (1, +-i, 0) lie on every circle of a plane; their images i', j' satisfy
i'^T w i' = 0 with w = K^-T K^-1 the image of the absolute conic (Zhang 2000; Meng & Hu 2003).
One circle per view does not fix i' (PAPER.md): each solver here uses one more projective cue.

- :func:`circular_points_from_ring`: two concentric circles. The isolated generalised
  eigenvector of (C_out, C_in) is the image c of the common centre; l = C_out c is the vanishing
  line (polar of the centre); i', j' = l n C_out.
- :func:`circular_point_pt2`: the seed paper's Inference 2 (Pascal hexagon of five conic points and
  i'), with i' constrained to the vanishing line, solved by complex Newton.
- :func:`circular_points_pt1`: Proposition 2 (four points + i' + j', j' = conj(i')), with i' on the
  vanishing line and a second hexagon through a fifth point, solved by Gauss-Newton.
- :func:`circular_points_huang`: two separated coplanar circles (Huang et al.): the degenerate
  member of their pencil that splits into two real lines gives the vanishing line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .conic import line_conic_intersection, normalize_conic


class CircularPointError(ValueError):
    """The conics do not determine the circular points (noise, wrong feature pairing)."""


def _dehom(p: np.ndarray) -> np.ndarray:
    return p / p[2]


def centre_image_from_ring(C_out: np.ndarray, C_in: np.ndarray) -> np.ndarray:
    """Image of the common centre of two concentric circles (homogeneous, real, p[2] = 1).

    For circles C_k = diag(1, 1, -r_k^2), C_in^-1 C_out = diag(1, 1, r_out^2 / r_in^2): the
    isolated eigenvalue's eigenvector is the centre; homographies preserve this structure."""
    A = normalize_conic(C_out)
    B = normalize_conic(C_in)
    w, V = np.linalg.eig(np.linalg.solve(B, A))
    w = np.real_if_close(w, tol=1e6)
    # isolated eigenvalue: the one farthest from the other two
    dist = [min(abs(w[i] - w[j]) for j in range(3) if j != i) for i in range(3)]
    k = int(np.argmax(dist))
    c = np.real(V[:, k])
    if abs(c[2]) < 1e-12 * np.linalg.norm(c):
        raise CircularPointError("ring conics give a centre at infinity: not a concentric pair")
    return _dehom(c)


def vanishing_line_from_centre(C: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Polar of the centre image with respect to the circle's image: l = C c, unit norm."""
    line = normalize_conic(C) @ c
    return line / np.linalg.norm(line)


def circular_points_from_ring(C_out: np.ndarray, C_in: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed form: (i', j') as complex homogeneous 3-vectors with third coordinate 1."""
    c = centre_image_from_ring(C_out, C_in)
    line = vanishing_line_from_centre(C_out, c)
    return _intersections(line, C_out)


def _intersections(line: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p, q = line_conic_intersection(line, C)
    if abs(p[2]) < 1e-15 or abs(q[2]) < 1e-15:
        raise CircularPointError("vanishing line meets the conic at infinity")
    p, q = p / p[2], q / q[2]
    if abs(p[0].imag) + abs(p[1].imag) < 1e-12 * (abs(p[0]) + abs(p[1])):
        raise CircularPointError("vanishing line meets the conic in real points: the conics are not "
                                 "images of circles of one plane")
    # order: i' has positive imaginary part of the first coordinate
    return (p, q) if p[0].imag >= 0 else (q, p)


def pascal_condition(pts: list[np.ndarray]) -> complex:
    """Pascal's condition for six points p1..p6 (homogeneous, possibly complex) on a conic:
    the intersections of opposite sides (p1p2, p4p5), (p2p3, p5p6), (p3p4, p6p1) are collinear,
    i.e. det[...] = 0. The determinant is multilinear, hence holomorphic in a complex point
    (no normalisation by |p|, which would break complex Newton): pass well-scaled coordinates."""
    p = pts
    x1 = np.cross(np.cross(p[0], p[1]), np.cross(p[3], p[4]))
    x2 = np.cross(np.cross(p[1], p[2]), np.cross(p[4], p[5]))
    x3 = np.cross(np.cross(p[2], p[3]), np.cross(p[5], p[0]))
    return complex(np.linalg.det(np.stack([x1, x2, x3])))


def _line_basis(line: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u, v spanning the line: points u + t v. u is the foot of the origin's perpendicular."""
    a, b, c = line
    n2 = a * a + b * b
    u = np.array([-a * c / n2, -b * c / n2, 1.0])
    v = np.array([-b, a, 0.0]) / np.sqrt(n2)
    return u, v


def _normalizing_transform(pts: np.ndarray) -> np.ndarray:
    """Similarity taking the points' centroid to 0 and their mean distance to 1."""
    m = pts.mean(axis=0)
    s = 1.0 / max(float(np.mean(np.linalg.norm(pts - m, axis=1))), 1e-12)
    return np.array([[s, 0, -s * m[0]], [0, s, -s * m[1]], [0, 0, 1.0]])


def _prepare(points5: np.ndarray, line: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    pts = np.asarray(points5, float)
    if pts.shape != (5, 2):
        raise ValueError(f"expected five conic points (5, 2), got {pts.shape}")
    T = _normalizing_transform(pts)
    hom = [T @ np.array([x, y, 1.0]) for x, y in pts]
    line_n = np.linalg.solve(T.T, np.asarray(line, float))
    return hom, line_n / np.linalg.norm(line_n), T


@dataclass(frozen=True)
class NewtonResult:
    point: np.ndarray  # complex homogeneous 3-vector, third coordinate 1
    iterations: int
    converged: bool


def circular_point_pt2(points5: np.ndarray, line: np.ndarray, start: complex | None = None,
                       tol: float = 1e-15, max_iter: int = 60) -> NewtonResult:
    """PT2 (seed paper, Inference 2): find i' with Pascal(p1..p5, i') = 0 and l^T i' = 0.

    i' = u + t v on the vanishing line, t complex; the Pascal determinant is a polynomial in t
    (quadratic: its roots are i' and j'), so Newton is run in complex arithmetic. It must not start
    on the real axis (the iterates would stay real). ``points5`` are (5, 2) image points on the
    conic; ``start`` is t0 in units of the points' mean distance from the line's foot point in
    normalised coordinates (default 1j)."""
    pts, line_n, T = _prepare(points5, line)
    u, v = _line_basis(line_n)
    scale_d = float(np.mean([np.linalg.norm(p[:2] - u[:2]) for p in pts]))
    t = complex(1j if start is None else start) * scale_d
    if abs(t.imag) < 1e-12:
        raise ValueError("pt2 Newton must not start on the real axis")

    def f(tt: complex) -> complex:
        return pascal_condition([*pts, u + tt * v])

    scale = max(abs(t), 1.0)
    for it in range(1, max_iter + 1):
        h = 1e-6 * scale
        ft = f(t)
        d = (f(t + h) - f(t - h)) / (2 * h)
        if d == 0:
            break
        step = ft / d  # f is quadratic in t: the central difference is its exact derivative
        t = t - step
        if abs(step) <= tol * max(abs(t), 1.0):
            return NewtonResult(_denormalize(u + t * v, T), it, True)
    return NewtonResult(_denormalize(u + t * v, T), max_iter, False)


def _denormalize(p: np.ndarray, T: np.ndarray) -> np.ndarray:
    q = np.linalg.solve(T, p)
    return q / q[2]


def circular_points_pt1(points5: np.ndarray, line: np.ndarray, start: complex | None = None,
                        max_iter: int = 100, tol: float = 1e-14) -> NewtonResult:
    """PT1 (seed paper, Proposition 2) made well-posed: i' = u + t v on the vanishing line,
    j' = conj(i'), and two hexagons (a, b, c, d, i', j') and (a, c, d, e, i', j') sharing three
    conic points. Real Gauss-Newton over (Re t, Im t) on the four real residuals. It can collapse
    to i' = j' (Im t -> 0, where both conditions vanish trivially): ``converged`` is False then.
    ``start`` as in :func:`circular_point_pt2`. From random starts Re, Im ~ N(0,1), U(0.2, 3) it
    reaches i' in about 3 of 4 cases (test_circular.py measures it); :data:`PT1_STARTS` are tried
    in turn by the calibration pipeline."""
    pts, line_n, T = _prepare(points5, line)
    a, b, c, d, e = pts
    u, v = _line_basis(line_n)
    scale_d = float(np.mean([np.linalg.norm(p[:2] - u[:2]) for p in pts]))
    t0 = complex(1j if start is None else start) * scale_d
    z = np.array([t0.real, t0.imag])

    def res(zz: np.ndarray) -> np.ndarray:
        t = complex(zz[0], zz[1])
        i_ = u + t * v
        j_ = u + np.conj(t) * v
        r1 = pascal_condition([a, b, c, d, i_, j_])
        r2 = pascal_condition([a, c, d, e, i_, j_])
        return np.array([r1.real, r1.imag, r2.real, r2.imag])

    scale = max(float(np.linalg.norm(z)), 1.0)
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        r = res(z)
        J = np.empty((4, 2))
        for k in range(2):
            h = 1e-7 * scale
            dz = np.zeros(2)
            dz[k] = h
            J[:, k] = (res(z + dz) - res(z - dz)) / (2 * h)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        z = z + step
        if float(np.linalg.norm(step)) <= tol * max(float(np.linalg.norm(z)), 1.0):
            break
    t = complex(z[0], z[1])
    collapsed = abs(t.imag) < 1e-6 * max(abs(t), 1.0)
    ok = bool(np.all(np.isfinite(z))) and not collapsed
    return NewtonResult(_denormalize(u + t * v, T), it, ok)


PT1_STARTS = (1j, 2j, 0.5 + 0.5j, -1 + 1j, 1 + 3j, 4j)


def _split_degenerate_conic(D: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Split a rank-2 symmetric D into two real lines l, m with D ~ (l m^T + m l^T) / 2."""
    w, V = np.linalg.eigh(D)
    order = np.argsort(np.abs(w))  # smallest |w| ~ 0 is the intersection point
    w1, w2 = w[order[1]], w[order[2]]
    e1, e2 = V[:, order[1]], V[:, order[2]]
    if w1 * w2 >= 0:
        return None  # lines are complex conjugate
    if w2 < 0:
        w1, w2, e1, e2 = w2, w1, e2, e1
    a, b = np.sqrt(w2), np.sqrt(-w1)
    return a * e2 + b * e1, a * e2 - b * e1


def _side(line: np.ndarray, C: np.ndarray) -> tuple[bool, float]:
    """Whether the line misses the ellipse C (True) and the sign of the ellipse centre."""
    p, _ = line_conic_intersection(line, C)
    misses = abs(p[0].imag) + abs(p[1].imag) + abs(p[2].imag) > 1e-12 * np.linalg.norm(np.abs(p))
    A = C[:2, :2]
    ctr = -np.linalg.solve(A, C[:2, 2])
    return misses, float(line @ np.array([ctr[0], ctr[1], 1.0]))


def vanishing_line_huang(C1: np.ndarray, C2: np.ndarray) -> np.ndarray:
    """Vanishing line of the plane of two separated coplanar circles (Huang et al.).

    Among the degenerate members C1 - lambda C2 of the pencil, the one that splits into two real
    lines contains the line at infinity's image and the radical axis; the vanishing line is the
    one with both ellipses on the same side (the radical axis separates them)."""
    A, B = normalize_conic(C1), normalize_conic(C2)
    lams = np.linalg.eigvals(np.linalg.solve(B, A))
    best: tuple[float, np.ndarray] | None = None
    for lam in lams:
        if abs(lam.imag) > 1e-6 * abs(lam):
            continue
        D = A - lam.real * B
        lines = _split_degenerate_conic(D / np.linalg.norm(D))
        if lines is None:
            continue
        for line in lines:
            line = line / np.linalg.norm(line)
            m1, s1 = _side(line, A)
            m2, s2 = _side(line, B)
            if m1 and m2 and s1 * s2 > 0:
                score = min(abs(s1), abs(s2))
                if best is None or score > best[0]:
                    best = (score, line)
    if best is None:
        raise CircularPointError("two-circle pencil has no real line pair with both ellipses on one "
                                 "side: circles not coplanar or not separated")
    return best[1]


def circular_points_huang(C1: np.ndarray, C2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(i', j') from two separated coplanar circles: vanishing line n each conic, averaged."""
    line = vanishing_line_huang(C1, C2)
    i1, j1 = _intersections(line, normalize_conic(C1))
    i2, j2 = _intersections(line, normalize_conic(C2))
    return (i1 + i2) / 2, (j1 + j2) / 2
