"""Lens models behind one interface: camera-frame point -> distorted normalised coordinates, its
Jacobians, and the inverse from distorted coordinates to a unit ray.

A ray, not x/z, is the unit of unprojection, so rays at or beyond 90 degrees from the optical
axis (fisheye) work everywhere. The models and their coefficient order are exactly OpenCV's and
ROS's (``sensor_msgs/CameraInfo.distortion_model``):

- ``plumb_bob``, D = (k1, k2, p1, p2, k3) and ``rational_polynomial``,
  D = (k1, k2, p1, p2, k3, k4, k5, k6) (OpenCV ``projectPoints``; Brown-Conrady with a rational
  radial factor): x = X/Z, y = Y/Z, r^2 = x^2 + y^2,
  R = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6),
  x_d = x R + 2 p1 x y + p2 (r^2 + 2 x^2), y_d = y R + p1 (r^2 + 2 y^2) + 2 p2 x y.
  Defined for Z > 0 only.
- ``equidistant``, D = (k1, k2, k3, k4) (OpenCV ``cv::fisheye``; Kannala & Brandt, PAMI 2006):
  theta = angle of the ray from the optical axis, theta_d = theta (1 + k1 theta^2 + k2 theta^4 +
  k3 theta^6 + k4 theta^8), (x_d, y_d) = theta_d (X, Y) / sqrt(X^2 + Y^2). OpenCV computes theta
  as atan(r) of x/z, which mirrors rays beyond 90 degrees; here theta = atan2(sqrt(X^2 + Y^2), Z)
  is the ray's own angle, identical inside 90 degrees and defined up to 180.

Pixels follow from K: u = fx x_d + s y_d + cx, v = fy y_d + cy (:mod:`.camera`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RAY_EPS = 1e-12  # relative size of (X, Y) against Z below which a ray is the optical axis


@dataclass(frozen=True)
class LensModel:
    """A named distortion model: ROS ``distortion_model`` string and coefficient names (D order)."""

    name: str
    coefficients: tuple[str, ...]

    @property
    def n(self) -> int:
        return len(self.coefficients)

    @property
    def wide(self) -> bool:
        """Whether rays at or beyond 90 degrees can be imaged (fisheye)."""
        return False

    def check(self, D: np.ndarray) -> np.ndarray:
        D = np.asarray(D, float).reshape(-1)
        if len(D) != self.n:
            raise ValueError(f"{self.name} has {self.n} distortion coefficients "
                             f"({', '.join(self.coefficients)}), got {len(D)}")
        return D

    def distort(self, X: np.ndarray, D: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) -> distorted normalised coordinates (N, 2)."""
        raise NotImplementedError

    def distort_with_jacobians(self, X: np.ndarray, D: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x_d (N, 2), d x_d / d X (N, 2, 3) and d x_d / d D (N, 2, n)."""
        raise NotImplementedError

    def distort_with_point_jacobian(self, X: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x_d (N, 2) and d x_d / d X (N, 2, 3) only (models may skip d x_d / d D)."""
        xd, dX, _ = self.distort_with_jacobians(X, D)
        return xd, dX

    def undistort(self, xd: np.ndarray, D: np.ndarray, strict: bool = True) -> np.ndarray:
        """Distorted normalised coordinates (N, 2) -> unit rays (N, 3); with ``strict``, NaN where
        the model is not invertible (beyond its monotonic range). Without it, the iteration's
        result is returned everywhere: a smooth function of D that an optimiser can cross a
        transient fold with."""
        raise NotImplementedError

    def max_angle(self, D: np.ndarray) -> float:
        """The largest ray angle (radians) up to which the model is monotonic in the radius."""
        raise NotImplementedError


def _unit(X: np.ndarray) -> np.ndarray:
    return X / np.linalg.norm(X, axis=-1, keepdims=True)


@dataclass(frozen=True)
class PolynomialModel(LensModel):
    """plumb_bob and rational_polynomial (module docstring); plumb_bob is the rational model with
    k4 = k5 = k6 = 0."""

    def _d8(self, D: np.ndarray) -> np.ndarray:
        D = self.check(D)
        return D if self.n == 8 else np.concatenate([D, np.zeros(3)])

    def distort_normalized(self, xy: np.ndarray, D: np.ndarray) -> np.ndarray:
        """The distortion on pinhole coordinates x = X/Z (..., 2)."""
        k1, k2, p1, p2, k3, k4, k5, k6 = self._d8(D)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.stack([xd, yd], axis=-1)

    def _radial(self, xy: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, ...]:
        """r^2, the rational factor's denominator, the factor R and dR/d(r^2)."""
        return self._radial_of(xy[..., 0], xy[..., 1], D)

    def _radial_of(self, x: np.ndarray, y: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`_radial` of the coordinates x, y."""
        k1, k2, _, _, k3, k4, k5, k6 = self._d8(D)
        r2 = x * x + y * y
        num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
        dradial = ((k1 + r2 * (2 * k2 + 3 * k3 * r2)) * den - num * (k4 + r2 * (2 * k5 + 3 * k6 * r2))) / (den * den)
        return r2, den, num / den, dradial

    def _jacobian_xy(self, xy: np.ndarray, D: np.ndarray, radial_terms: tuple[np.ndarray, ...] | None = None
                     ) -> tuple[np.ndarray, ...]:
        """d x_d / d (x, y) as (a, b, c, d) = (dxd/dx, dxd/dy, dyd/dx, dyd/dy); ``radial_terms``:
        :meth:`_radial` of the same points, if the caller has it."""
        return self._jacobian_of(xy[..., 0], xy[..., 1], D, radial_terms)

    def _jacobian_of(self, x: np.ndarray, y: np.ndarray, D: np.ndarray,
                     radial_terms: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, ...]:
        """:meth:`_jacobian_xy` of the coordinates x, y."""
        p1, p2 = self._d8(D)[2:4]
        _, _, radial, dradial = radial_terms if radial_terms is not None else self._radial_of(x, y, D)
        b = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
        return (radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x, b, b,
                radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x)

    def _coefficient_jacobian(self, xy: np.ndarray, terms: tuple[np.ndarray, ...]) -> np.ndarray:
        """d x_d / d D (..., 2, n) from :meth:`_radial`'s terms of the same points."""
        x, y = xy[..., 0], xy[..., 1]
        r2, den, radial, _ = terms
        r4, r6 = r2 * r2, r2 * r2 * r2
        xs, ys = x / den, y / den
        dD = np.empty((*xy.shape[:-1], 2, self.n))
        dD[..., 0, 0], dD[..., 0, 1], dD[..., 0, 4] = xs * r2, xs * r4, xs * r6
        dD[..., 1, 0], dD[..., 1, 1], dD[..., 1, 4] = ys * r2, ys * r4, ys * r6
        dD[..., 0, 2] = dD[..., 1, 3] = 2 * x * y
        dD[..., 0, 3] = r2 + 2 * x * x
        dD[..., 1, 2] = r2 + 2 * y * y
        if self.n == 8:
            for k, rk in enumerate((r2, r4, r6)):
                dD[..., 0, 5 + k] = -xs * radial * rk
                dD[..., 1, 5 + k] = -ys * radial * rk
        return dD

    def distort(self, X: np.ndarray, D: np.ndarray) -> np.ndarray:
        X = np.asarray(X, float)
        return self.distort_normalized(X[..., :2] / X[..., 2:3], D)

    def _with_jacobians(self, X: np.ndarray, D: np.ndarray, coefficients: bool
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """x_d, d x_d / d X = (d x_d / d (x, y)) (d (x, y) / d X) with (x, y) = (X/Z, Y/Z), and
        (``coefficients``) d x_d / d D; the radial factor computed once for all three."""
        X = np.asarray(X, float)
        iz = 1.0 / X[:, 2]
        x, y = X[:, 0] * iz, X[:, 1] * iz
        p1, p2 = self._d8(D)[2:4]
        terms = self._radial_of(x, y, D)
        r2, _, radial, _ = terms
        xd = np.empty((len(X), 2))
        xd[:, 0] = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        xd[:, 1] = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        a, b, c, d = self._jacobian_of(x, y, D, terms)
        mx, my = -x * iz, -y * iz
        dX = np.empty((len(X), 2, 3))
        dX[:, 0, 0], dX[:, 0, 1], dX[:, 0, 2] = a * iz, b * iz, a * mx + b * my
        dX[:, 1, 0], dX[:, 1, 1], dX[:, 1, 2] = c * iz, d * iz, c * mx + d * my
        return xd, dX, self._coefficient_jacobian(np.stack([x, y], -1), terms) if coefficients else None

    def distort_with_jacobians(self, X: np.ndarray, D: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xd, dX, dD = self._with_jacobians(X, D, True)
        assert dD is not None
        return xd, dX, dD

    def distort_with_point_jacobian(self, X: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xd, dX, _ = self._with_jacobians(X, D, False)
        return xd, dX

    def undistort_normalized(self, xd: np.ndarray, D: np.ndarray, iterations: int = 8) -> np.ndarray:
        """Pinhole coordinates x = X/Z of distorted ones, by Newton's method from x = x_d."""
        xd = np.asarray(xd, float)
        D = self.check(D)
        if not np.any(D != 0):
            return xd.copy()
        xy = xd.copy()
        p1, p2 = self._d8(D)[2:4]
        for _ in range(iterations):
            x, y = xy[..., 0], xy[..., 1]
            terms = self._radial(xy, D)
            r2, _, radial, _ = terms
            fx = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd[..., 0]
            fy = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - xd[..., 1]
            a, b, c, d = self._jacobian_xy(xy, D, terms)
            det = a * d - b * c
            det = np.where(np.abs(det) < 1e-12, 1e-12, det)
            dx = (d * fx - b * fy) / det
            dy = (-c * fx + a * fy) / det
            xy[..., 0] -= dx
            xy[..., 1] -= dy
            if np.max(np.abs(dx)) + np.max(np.abs(dy)) < 1e-13 * (1.0 + float(np.max(np.abs(xy)))):
                break
        return xy

    def undistort(self, xd: np.ndarray, D: np.ndarray, strict: bool = True) -> np.ndarray:
        """Rays of the branch where the radius still grows (up to :meth:`max_angle`); with
        ``strict``, NaN beyond the fold, where Newton may land on the model's other branch (a ray
        on the far side that projects to the same point)."""
        xy = self.undistort_normalized(xd, D)
        rays = _unit(np.concatenate([xy, np.ones((*xy.shape[:-1], 1))], -1))
        if strict and np.any(np.asarray(D) != 0):
            r_max = np.tan(self.max_angle(D))
            back = self.distort_normalized(xy, D)
            bad = (np.hypot(xy[..., 0], xy[..., 1]) > r_max) | ~np.isfinite(xy).all(-1) \
                | (np.abs(back - xd).max(-1) > 1e-7 * (1 + np.abs(xd).max(-1)))
            rays[bad] = np.nan
        return rays

    def max_angle(self, D: np.ndarray) -> float:
        """Where r_d = r R(r^2) stops increasing (radial part only), as a ray angle."""
        k1, k2, _, _, k3, k4, k5, k6 = self._d8(D)
        r = np.linspace(0, 20, 20001)[1:]
        r2 = r * r
        rd = r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        bad = np.flatnonzero(np.diff(rd) <= 0)
        r_max = r[bad[0]] if len(bad) else r[-1]
        return float(np.arctan(r_max))


@dataclass(frozen=True)
class EquidistantModel(LensModel):
    """OpenCV's fisheye model with the ray's own angle (module docstring)."""

    @property
    def wide(self) -> bool:
        return True

    @staticmethod
    def _theta_d(theta: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """theta_d and d theta_d / d theta."""
        k1, k2, k3, k4 = D
        t2 = theta * theta
        g = theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
        dg = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
        return g, dg

    @staticmethod
    def _angles(X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """rho = |(X, Y)|, theta, the unit direction (a, b) of (X, Y) ((1, 0) on the axis) and
        whether the point is on the axis."""
        rho = np.hypot(X[:, 0], X[:, 1])
        theta = np.arctan2(rho, X[:, 2])
        axis = rho <= RAY_EPS * np.abs(X[:, 2])
        safe = np.where(axis, 1.0, rho)
        a = np.where(axis, 1.0, X[:, 0] / safe)
        b = np.where(axis, 0.0, X[:, 1] / safe)
        return rho, theta, a, b, axis

    def distort(self, X: np.ndarray, D: np.ndarray) -> np.ndarray:
        D = self.check(D)
        X = np.asarray(X, float).reshape(-1, 3)
        _, theta, a, b, _ = self._angles(X)
        g, _ = self._theta_d(theta, D)
        return np.stack([g * a, g * b], -1)

    def distort_with_jacobians(self, X: np.ndarray, D: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        D = self.check(D)
        X = np.asarray(X, float)
        rho, theta, a, b, axis = self._angles(X)
        z = X[:, 2]
        g, dg = self._theta_d(theta, D)
        n2 = rho * rho + z * z
        s = np.where(axis, 1.0 / np.where(axis, z, 1.0), g / np.where(axis, 1.0, rho))  # g / rho, limit 1/Z
        gz = dg * z / n2
        J = np.empty((len(X), 2, 3))
        J[:, 0, 0] = gz * a * a + s * b * b
        J[:, 0, 1] = J[:, 1, 0] = (gz - s) * a * b
        J[:, 1, 1] = gz * b * b + s * a * a
        J[:, 0, 2] = -dg * rho * a / n2
        J[:, 1, 2] = -dg * rho * b / n2
        powers = np.stack([theta ** (2 * i + 3) for i in range(4)], -1)
        dD = np.stack([powers * a[:, None], powers * b[:, None]], 1)
        return np.stack([g * a, g * b], -1), J, dD

    def undistort(self, xd: np.ndarray, D: np.ndarray, strict: bool = True, iterations: int = 30) -> np.ndarray:
        """theta from theta_d by Newton's method on the monotonic branch [0, max_angle] (clipped
        there); with ``strict``, NaN where theta_d is beyond the branch."""
        D = self.check(D)
        xd = np.asarray(xd, float)
        shape = xd.shape[:-1]
        xd = xd.reshape(-1, 2)
        td = np.hypot(xd[:, 0], xd[:, 1])
        t_max = self.max_angle(D)
        g_max, _ = self._theta_d(np.array([t_max]), D)
        theta = np.minimum(td, t_max)
        for _ in range(iterations):
            g, dg = self._theta_d(theta, D)
            step = (g - td) / np.where(dg > 0, dg, np.inf)
            theta = np.clip(theta - step, 0.0, t_max)
            if np.max(np.abs(step)) < 1e-13 * (1.0 + float(np.max(theta, initial=0.0))):
                break
        g, _ = self._theta_d(theta, D)
        ok = (td <= g_max[0]) & (np.abs(g - td) <= 1e-9 * (1 + td)) if strict else np.ones(len(td), bool)
        safe = np.where(td > 0, td, 1.0)
        st = np.sin(theta)
        rays = np.stack([st * xd[:, 0] / safe, st * xd[:, 1] / safe, np.cos(theta)], -1)
        rays[~ok] = np.nan
        return rays.reshape(*shape, 3)

    def max_angle(self, D: np.ndarray) -> float:
        """The first angle where d theta_d / d theta reaches 0, at most pi."""
        D = self.check(D)
        theta = np.linspace(0.0, np.pi, 3601)
        _, dg = self._theta_d(theta, D)
        bad = np.flatnonzero(dg <= 0)
        return float(theta[bad[0] - 1]) if len(bad) else float(np.pi)


PLUMB_BOB = PolynomialModel("plumb_bob", ("k1", "k2", "p1", "p2", "k3"))
RATIONAL = PolynomialModel("rational_polynomial", ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"))
EQUIDISTANT = EquidistantModel("equidistant", ("k1", "k2", "k3", "k4"))
MODELS: dict[str, LensModel] = {m.name: m for m in (PLUMB_BOB, RATIONAL, EQUIDISTANT)}

# what a user asks for (--distortion, distortion_model) -> (model, the coefficients estimated)
DISTORTION_CHOICES: dict[str, tuple[LensModel, tuple[str, ...]]] = {
    "plumb_bob": (PLUMB_BOB, PLUMB_BOB.coefficients),
    "plumb_bob_k3_fixed": (PLUMB_BOB, ("k1", "k2", "p1", "p2")),
    "radial": (PLUMB_BOB, ("k1", "k2")),
    "none": (PLUMB_BOB, ()),
    "rational_polynomial": (RATIONAL, RATIONAL.coefficients),
    "equidistant": (EQUIDISTANT, EQUIDISTANT.coefficients),
}


def lens_model(name: str) -> LensModel:
    """The model of a ROS ``distortion_model`` string or a ``DISTORTION_CHOICES`` key."""
    if name in MODELS:
        return MODELS[name]
    if name in DISTORTION_CHOICES:
        return DISTORTION_CHOICES[name][0]
    raise ValueError(f"unknown distortion model {name!r}; choose one of {', '.join(DISTORTION_CHOICES)}")


def model_for_coefficients(D: np.ndarray, name: str = "") -> LensModel:
    """The model named, or (no name) the one with that many coefficients (5 plumb_bob, 8 rational;
    4 is ambiguous only in principle: ROS writes 4 for equidistant)."""
    if name:
        return lens_model(name)
    n = len(np.asarray(D).reshape(-1))
    by_n = {5: PLUMB_BOB, 8: RATIONAL, 4: EQUIDISTANT}
    if n not in by_n:
        raise ValueError(f"{n} distortion coefficients match no model (5 plumb_bob, 8 rational_polynomial, "
                         "4 equidistant)")
    return by_n[n]
