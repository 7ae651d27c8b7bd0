"""mrcal's ``LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=.._Ny=.._fov_x_deg=..`` lens model: its
projection (so an exported model can be checked and measured here) and its unprojection.

Definition (mrcal's "splined models" page and its C implementation of the projection): a point p
in the camera frame has the normalised stereographic projection u = 2 p_xy / (|p| + p_z)
(|u| = 2 tan(theta / 2), defined up to 180 degrees); two cubic B-spline surfaces over u give a
correction du(u), and q = f (u + du) + c. The control points lie on a regular Nx x Ny grid in u
with spacing 1 / s, s = (Nx - 3) / (2 u_edge), u_edge = 2 tan(fov_x / 4); the grid index of u is
i = u s + (N - 1) / 2, the patch's first knot i0 = floor(i) clamped to [1, N - 3] (outside the
grid the nearest patch is extrapolated), and du = sum_ab B_a(i_y - i0_y) B_b(i_x - i0_x)
c[i0_y - 1 + a, i0_x - 1 + b] with the uniform cubic B-spline basis B_0 = (1 - t)^3 / 6,
B_1 = (3 t^3 - 6 t^2 + 4) / 6, B_2 = (-3 t^3 + 3 t^2 + 3 t + 1) / 6, B_3 = t^3 / 6. Intrinsics:
fx fy cx cy, then the control points row by row (y), each (du_x, du_y).

For fixed fx fy cx cy the projection is linear in the control points, which makes a refit into
this model a linear least-squares problem (:func:`design_matrix`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..geometry import Camera, ImageSize, LensModel

PATTERN = re.compile(r"^LENSMODEL_SPLINED_STEREOGRAPHIC_order=(\d+)_Nx=(\d+)_Ny=(\d+)_fov_x_deg=(\d+)$")


def bspline3(t: np.ndarray) -> np.ndarray:
    """The uniform cubic B-spline weights (N, 4) of the four knots around local coordinates t (N,)."""
    t2, t3 = t * t, t * t * t
    return np.stack([(1 - t) ** 3 / 6, (3 * t3 - 6 * t2 + 4) / 6, (-3 * t3 + 3 * t2 + 3 * t + 1) / 6, t3 / 6], -1)


def stereographic(p: np.ndarray) -> np.ndarray:
    """u = 2 p_xy / (|p| + p_z) of camera-frame points (N, 3) -> (N, 2)."""
    p = np.asarray(p, float)
    return 2 * p[:, :2] / (np.linalg.norm(p, axis=1) + p[:, 2])[:, None]


def ray_of_stereographic(u: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) of normalised stereographic coordinates (N, 2)."""
    r = np.hypot(u[:, 0], u[:, 1])
    theta = 2 * np.arctan(r / 2)
    safe = np.where(r > 0, r, 1.0)
    s = np.where(r > 0, np.sin(theta) / safe, 0.5)
    return np.stack([u[:, 0] * s, u[:, 1] * s, np.cos(theta)], -1)


@dataclass(frozen=True)
class SplinedModel:
    """An mrcal splined stereographic model (module docstring); cubic (order 3) only."""

    Nx: int
    Ny: int
    fov_x_deg: int
    intrinsics: np.ndarray  # fx fy cx cy, then 2 Nx Ny control values
    width: int
    height: int

    def __post_init__(self) -> None:
        if self.Nx < 4 or self.Ny < 4 or not 0 < self.fov_x_deg < 360:
            raise ValueError(f"a cubic splined model needs Nx, Ny >= 4 and 0 < fov_x_deg < 360, got {self.Nx}, "
                             f"{self.Ny}, {self.fov_x_deg}")
        if len(self.intrinsics) != 4 + 2 * self.Nx * self.Ny:
            raise ValueError(f"{self.lensmodel} has {4 + 2 * self.Nx * self.Ny} intrinsics, got {len(self.intrinsics)}")

    @property
    def lensmodel(self) -> str:
        return f"LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx={self.Nx}_Ny={self.Ny}_fov_x_deg={self.fov_x_deg}"

    @staticmethod
    def segments_per_u(Nx: int, fov_x_deg: float) -> float:
        u_edge = 2 * np.tan(np.radians(fov_x_deg) / 4)
        return (Nx - 3) / (2 * u_edge)

    def _patches(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The first knot (ix0, iy0) of each point's patch and the local coordinates (tx, ty)."""
        s = self.segments_per_u(self.Nx, self.fov_x_deg)
        ix = u[:, 0] * s + (self.Nx - 1) / 2
        iy = u[:, 1] * s + (self.Ny - 1) / 2
        ix0 = np.clip(np.trunc(ix).astype(int), 1, self.Nx - 3)  # C's (int) cast, then clamped
        iy0 = np.clip(np.trunc(iy).astype(int), 1, self.Ny - 3)
        return ix0, iy0, ix - ix0, iy - iy0

    def correction(self, u: np.ndarray) -> np.ndarray:
        """du (N, 2) at normalised stereographic coordinates u (N, 2)."""
        ix0, iy0, tx, ty = self._patches(u)
        c = np.asarray(self.intrinsics[4:], float).reshape(self.Ny, self.Nx, 2)
        bx, by = bspline3(tx), bspline3(ty)
        out = np.zeros((len(u), 2))
        for a in range(4):
            for b in range(4):
                out += (by[:, a] * bx[:, b])[:, None] * c[iy0 - 1 + a, ix0 - 1 + b]
        return out

    def project(self, p: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) -> pixels (N, 2)."""
        u = stereographic(np.asarray(p, float).reshape(-1, 3))
        fx, fy, cx, cy = self.intrinsics[:4]
        w = u + self.correction(u)
        return np.stack([fx * w[:, 0] + cx, fy * w[:, 1] + cy], -1)

    def unproject(self, q: np.ndarray, iterations: int = 30) -> np.ndarray:
        """Pixels (N, 2) -> unit rays (N, 3), Newton on u + du(u) = (q - c) / f (Jacobian by central
        differences); NaN where it does not converge to 1e-10."""
        fx, fy, cx, cy = self.intrinsics[:4]
        target = np.stack([(q[:, 0] - cx) / fx, (q[:, 1] - cy) / fy], -1)
        u = target.copy()
        h = 1e-7
        for _ in range(iterations):
            r = u + self.correction(u) - target
            if not len(r) or np.abs(r).max() < 1e-13:
                break
            J = np.empty((len(u), 2, 2))
            for k in range(2):
                e = np.zeros(2)
                e[k] = h
                J[:, :, k] = (self.correction(u + e) - self.correction(u - e)) / (2 * h)
            J[:, 0, 0] += 1
            J[:, 1, 1] += 1
            u = u - np.linalg.solve(J, r[..., None])[..., 0]
        bad = np.abs(u + self.correction(u) - target).max(1) > 1e-10
        rays = ray_of_stereographic(u)
        rays[bad] = np.nan
        return rays

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def design_matrix(model_shape: tuple[int, int, int], u: np.ndarray) -> np.ndarray:
    """A (N, Nx Ny) with du_k = A c_k for either component k (c_k the control values of component
    k, row by row): the spline's weights of every point on every knot. ``model_shape``: (Nx, Ny,
    fov_x_deg)."""
    Nx, Ny, fov = model_shape
    probe = SplinedModel(Nx, Ny, fov, np.zeros(4 + 2 * Nx * Ny), 1, 1)
    ix0, iy0, tx, ty = probe._patches(u)
    bx, by = bspline3(tx), bspline3(ty)
    A = np.zeros((len(u), Nx * Ny))
    rows = np.arange(len(u))
    for a in range(4):
        for b in range(4):
            np.add.at(A, (rows, (iy0 - 1 + a) * Nx + (ix0 - 1 + b)), by[:, a] * bx[:, b])
    return A


def parse_lensmodel(name: str) -> tuple[int, int, int, int] | None:
    """(order, Nx, Ny, fov_x_deg) of a splined model's name, or None."""
    m = PATTERN.match(name)
    return None if m is None else tuple(int(g) for g in m.groups())  # type: ignore[return-value]


@dataclass(frozen=True)
class SplinedLens(LensModel):
    """The lens of a :class:`SplinedCamera` as far as the projection difference needs one: wide
    (stereographic: defined up to 180 degrees), no coefficients of ours."""

    @property
    def wide(self) -> bool:
        return True

    def check(self, D: np.ndarray) -> np.ndarray:
        return np.asarray(D, float)

    def max_angle(self, D: np.ndarray) -> float:
        return float(np.pi) * 0.999


SPLINED_LENS = SplinedLens("mrcal_splined", ())


@dataclass(frozen=True)
class SplinedCamera(Camera):
    """A camera whose projection is an mrcal splined model (K: its fx fy cx cy; D unused)."""

    spline: SplinedModel | None = None

    @property
    def lens(self) -> LensModel:
        return SPLINED_LENS

    def project(self, X: np.ndarray) -> np.ndarray:
        assert self.spline is not None
        return self.spline.project(X)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        assert self.spline is not None
        return self.spline.unproject(np.asarray(uv, float).reshape(-1, 2)).reshape(*np.shape(uv)[:-1], 3)


def splined_camera(model: SplinedModel) -> SplinedCamera:
    fx, fy, cx, cy = model.intrinsics[:4]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return SplinedCamera(K, np.zeros(0), model.width, model.height, "mrcal_splined", spline=model)
