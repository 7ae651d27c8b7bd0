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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import PascalCalibError
from .conic import line_conic_intersection, normalize_conic


class CircularPointError(PascalCalibError):
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


# Stopping rules follow the rounding of the residual, never machine epsilon itself: a Newton step
# below STEP_RTOL of the root's size means the next one would be below the rounding of the
# Pascal determinant (quadratic convergence), and a residual within ROUNDING_FACTOR * eps of
# the sum of the magnitudes of its terms is rounding noise (Higham, Accuracy and Stability of
# Numerical Algorithms, 2nd ed., section 5.1: the error bound of evaluating a polynomial).
STEP_RTOL = 1e-12
ROUNDING_FACTOR = 64.0
_EPS = float(np.finfo(float).eps)


def _polynomial_in_t(f: Callable[[complex], complex], scale: float) -> np.ndarray:
    """Coefficients (c0, c1, c2) of a function known to be a quadratic polynomial in t, from its
    values at t = 0, +-scale (exact interpolation; ``scale`` keeps the nodes well conditioned)."""
    f0, fp, fm = f(0.0), f(scale), f(-scale)
    return np.array([f0, (fp - fm) / (2 * scale), (fp + fm - 2 * f0) / (2 * scale**2)], complex)


def circular_point_pt2(points5: np.ndarray, line: np.ndarray, start: complex | None = None,
                       max_iter: int = 60) -> NewtonResult:
    """PT2 (seed paper, Inference 2): find i' with Pascal(p1..p5, i') = 0 and l^T i' = 0.

    i' = u + t v on the vanishing line, t complex. The Pascal determinant is multilinear in the
    six points and the sixth appears in two of its three rows, so it is a quadratic polynomial
    P(t) = c0 + c1 t + c2 t^2 (its roots are i' and j'); the coefficients are interpolated
    exactly, and Newton runs on P with its analytic derivative in complex arithmetic. It must not
    start on the real axis (the iterates would stay real). It stops when the step is below
    ``STEP_RTOL`` of |t| or P(t) is at its rounding level; a root on the real axis (the line
    touches the conic: i' = j' real) is not a circular point and is reported as not converged.
    ``points5`` are (5, 2) image points on the conic; ``start`` is t0 in units of the points'
    mean distance from the line's foot point in normalised coordinates (default 1j)."""
    pts, line_n, T = _prepare(points5, line)
    u, v = _line_basis(line_n)
    scale_d = float(np.mean([np.linalg.norm(p[:2] - u[:2]) for p in pts]))
    t = complex(1j if start is None else start) * scale_d
    if abs(t.imag) < 1e-12 * max(abs(t), 1.0):
        raise ValueError("pt2 Newton must not start on the real axis")
    c0, c1, c2 = _polynomial_in_t(lambda tt: pascal_condition([*pts, u + tt * v]), max(scale_d, 1.0))
    size = max(scale_d, 1.0)
    for it in range(1, max_iter + 1):
        value = c0 + t * (c1 + t * c2)
        floor = ROUNDING_FACTOR * _EPS * (abs(c0) + abs(c1) * abs(t) + abs(c2) * abs(t) ** 2)
        if abs(value) <= floor:
            return _pt2_result(u + t * v, T, it, t, size)
        d = c1 + 2 * c2 * t
        if d == 0:
            break
        step = value / d
        t = t - step
        if abs(step) <= STEP_RTOL * max(abs(t), size):
            return _pt2_result(u + t * v, T, it, t, size)
    return NewtonResult(_denormalize(u + t * v, T), max_iter, False)


def _pt2_result(p: np.ndarray, T: np.ndarray, it: int, t: complex, size: float) -> NewtonResult:
    real_root = abs(t.imag) < 1e-6 * max(abs(t), size)
    return NewtonResult(_denormalize(p, T), it, not real_root)


def _denormalize(p: np.ndarray, T: np.ndarray) -> np.ndarray:
    q = np.linalg.solve(T, p)
    return q / q[2]


def _bipolynomial(f: Callable[[complex, complex], complex], scale: float) -> np.ndarray:
    """Coefficients c[j, k] of a function known to be of degree <= 2 in each of (t, s),
    f = sum c[j, k] t^j s^k, by exact interpolation on the nodes {0, +-scale}^2."""
    nodes = np.array([0.0, scale, -scale])
    V = np.vander(nodes, 3, increasing=True)  # V[a, j] = nodes[a]^j
    F = np.array([[f(ta, sb) for sb in nodes] for ta in nodes], complex)
    Vi = np.linalg.inv(V)
    return Vi @ F @ Vi.T


def _bipoly_value_and_partials(c: np.ndarray, t: complex, s: complex) -> tuple[complex, complex, complex, float]:
    """f, df/dt, df/ds of sum c[j, k] t^j s^k, and the sum of the terms' magnitudes."""
    pt = np.array([1, t, t * t])
    ps = np.array([1, s, s * s])
    dt = np.array([0, 1, 2 * t])
    ds = np.array([0, 1, 2 * s])
    mag = float(np.abs(c).ravel() @ np.outer(np.abs(pt), np.abs(ps)).ravel())
    return complex(pt @ c @ ps), complex(dt @ c @ ps), complex(pt @ c @ ds), mag


def circular_points_pt1(points5: np.ndarray, line: np.ndarray, start: complex | None = None,
                        max_iter: int = 100) -> NewtonResult:
    """PT1 (seed paper, Proposition 2) made well-posed: i' = u + t v on the vanishing line,
    j' = conj(i'), and two hexagons (a, b, c, d, i', j') and (a, c, d, e, i', j') sharing three
    conic points. Each Pascal determinant is multilinear in the points, with i' and j' each in two
    of its rows: a polynomial of degree <= 2 in t and in s = conj(t) separately, interpolated
    exactly; with t = x + iy its real Jacobian is d/dx = P_t + P_s, d/dy = i (P_t - P_s)
    (Wirtinger). Gauss-Newton over (x, y) on the four real residuals, stopped by the same rules
    as :func:`circular_point_pt2`. It can collapse to i' = j' (Im t -> 0, where both conditions
    vanish trivially): ``converged`` is False then. ``start`` as in :func:`circular_point_pt2`.
    From random starts Re, Im ~ N(0,1), U(0.2, 3) it reaches i' in about 3 of 4 cases
    (test_circular.py measures it); :data:`PT1_STARTS` are tried in turn by the pipeline."""
    pts, line_n, T = _prepare(points5, line)
    a, b, c, d, e = pts
    u, v = _line_basis(line_n)
    scale_d = float(np.mean([np.linalg.norm(p[:2] - u[:2]) for p in pts]))
    size = max(scale_d, 1.0)
    t0 = complex(1j if start is None else start) * scale_d
    def hexagon_condition(four: tuple[np.ndarray, ...]) -> Callable[[complex, complex], complex]:
        return lambda tt, ss: pascal_condition([*four, u + tt * v, u + ss * v])

    polys = [_bipolynomial(hexagon_condition(four), size) for four in ((a, b, c, d), (a, c, d, e))]
    z = np.array([t0.real, t0.imag])
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        t = complex(z[0], z[1])
        r = np.empty(4)
        J = np.empty((4, 2))
        at_floor = True
        for k, cpoly in enumerate(polys):
            f, ft, fs, mag = _bipoly_value_and_partials(cpoly, t, t.conjugate())
            at_floor &= abs(f) <= ROUNDING_FACTOR * _EPS * mag
            dx, dy = ft + fs, 1j * (ft - fs)
            r[2 * k: 2 * k + 2] = f.real, f.imag
            J[2 * k: 2 * k + 2] = [[dx.real, dy.real], [dx.imag, dy.imag]]
        if at_floor or not np.all(np.isfinite(J)):
            break
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        z = z + step
        if float(np.linalg.norm(step)) <= STEP_RTOL * max(float(np.linalg.norm(z)), size):
            break
    t = complex(z[0], z[1])
    collapsed = abs(t.imag) < 1e-6 * max(abs(t), size)
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


# Eigenvalues of the pencil closer than this (relative) are one double eigenvalue split by rounding:
# a double eigenvalue moves by O(sqrt(perturbation)), ~1e-8 for conics known to ~1e-16 relative,
# while a noisy but separated pair of circles gives eigenvalues that differ at the 1e-2 level.
# The eigenvalues of B^-1 A do not depend on the image coordinates, so neither does this test.
DOUBLE_EIGENVALUE_RTOL = 1e-5


def _pencil_degenerate_members(A: np.ndarray, B: np.ndarray) -> list[tuple[float, bool]]:
    """Real lambdas with A - lambda B degenerate, each with whether it is a double eigenvalue.
    Eigenvalues of B^-1 A that rounding has split from a double one (into a complex pair or two
    close reals) are merged into one, on purpose."""
    lams = list(np.linalg.eigvals(np.linalg.solve(B, A)))
    out: list[tuple[float, bool]] = []
    used = [False] * len(lams)
    for i, li in enumerate(lams):
        if used[i]:
            continue
        group = [li]
        for j in range(i + 1, len(lams)):
            if not used[j] and abs(lams[j] - li) <= DOUBLE_EIGENVALUE_RTOL * max(abs(li), abs(lams[j])):
                group.append(lams[j])
                used[j] = True
        lam = complex(np.mean(group))
        if abs(lam.imag) <= DOUBLE_EIGENVALUE_RTOL * abs(lam):
            out.append((lam.real, len(group) > 1))
    return out


def _lines_of_degenerate_conic(D: np.ndarray, double: bool) -> list[np.ndarray]:
    """The real lines of a degenerate conic: the dominant eigenvector for a double line
    (D ~ l l^T), else the two lines of a real pair, none for complex conjugate lines."""
    if double:
        w, V = np.linalg.eigh(D)
        return [V[:, int(np.argmax(np.abs(w)))]]
    lines = _split_degenerate_conic(D / np.linalg.norm(D))
    return [] if lines is None else list(lines)


def vanishing_line_huang(C1: np.ndarray, C2: np.ndarray) -> np.ndarray:
    """Vanishing line of the plane of two separated coplanar circles (Huang et al.).

    Among the degenerate members C1 - lambda C2 of the pencil, the one that splits into two real
    lines contains the line at infinity's image and the radical axis; the vanishing line is the
    one with both ellipses on the same side (the radical axis separates them). For concentric
    circles the member is the vanishing line counted twice (a double eigenvalue, which rounding
    splits: merged on purpose, see :func:`_pencil_degenerate_members`)."""
    A, B = normalize_conic(C1), normalize_conic(C2)
    best: tuple[float, np.ndarray] | None = None
    for lam, double in _pencil_degenerate_members(A, B):
        for line in _lines_of_degenerate_conic(A - lam * B, double):
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
