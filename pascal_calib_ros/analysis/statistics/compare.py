"""Projection difference between two calibrations of one camera (``pascal-calib diff``).

After mrcal's ``projection_diff`` / ``mrcal-show-projection-diff``
(http://mrcal.secretsauce.net/differencing.html). Two calibrations of the same lens disagree on
where the camera frame is, not only on the lens: each solve places the frame a little differently
against the housing (a principal point traded for a small rotation of every pose). Comparing the
raw projections would report that frame difference as a lens difference, so the implied
transformation between the two frames is fitted first and only what it cannot explain is
reported:

1. a grid of pixels q_i over camera A's image (inside a region, if given);
2. each is unprojected by A to a unit ray v_i and, at range r, to the point p_i = r v_i
   (r = infinity: the ray itself);
3. the implied transformation T = (R, t) from A's frame to B's is fitted by least squares in
   pixels, min_T sum_i |project_B(R p_i + t) - q_i|^2, started from the rotation that aligns A's
   rays with B's unprojections of the same pixels (Kabsch / Wahba,
   ``Rotation.align_vectors``). At infinity t has no effect and the fit is rotation-only; at a
   finite range R and t are both fitted, as mrcal does (a translation can then absorb part of a
   focal-length difference, which is why the difference depends on the range);
4. the difference at q_i is project_B(R p_i + t) - q_i.

mrcal maximises sum_i w_i cos(angle between B's ray and R p_i + t) (with weights from the
projection uncertainty, and by default fits only near the image centre); this module minimises
the unweighted pixel residual over the whole region, which for small differences is the same
fit up to the weighting. Grid points that either model cannot handle (A's unprojection fails, or
R p_i + t lies beyond B's monotonic range or behind a non-fisheye B) are left out and counted.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import PascalCalibError
from ...geometry import Camera, ImageSize, Transform, grid_pixels, grid_shape, hulls_mask
from ...io import ReportJsonError, read_view_hulls

DEFAULT_STEP = 16.0  # px between grid points
MIN_POINTS = 3  # fewer common grid points leave the rotation undetermined


class CompareError(PascalCalibError):
    """The two calibrations cannot be compared (different image sizes, no common field, bad
    region or camera file)."""


@dataclass(frozen=True)
class ProjectionDiff:
    """The difference between cameras A and B after the implied transformation (module docstring).

    ``pixels`` (N, 2): grid points of A's image that both models handle; ``difference`` (N, 2):
    project_B(R p_i + t) - q_i in pixels; ``transform``: T maps A's camera frame into B's
    (p_B = R p_A + t; t = 0 at infinite range); ``distance``: the range r in metres (None:
    infinity); ``n_excluded``: grid points inside the region left out.
    """

    pixels: np.ndarray
    difference: np.ndarray
    transform: Transform
    distance: float | None
    step: float
    width: int
    height: int
    n_excluded: int = 0

    @property
    def magnitude(self) -> np.ndarray:
        """|difference| per point (N,), px."""
        return np.asarray(np.linalg.norm(self.difference, axis=1))

    @property
    def n(self) -> int:
        return len(self.pixels)

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(np.sum(self.difference ** 2, axis=1))))

    @property
    def max(self) -> float:
        return float(self.magnitude.max())

    @property
    def rotvec(self) -> np.ndarray:
        """The fitted rotation as axis * angle (radians)."""
        return self.transform.rotvec

    @property
    def rotation_deg(self) -> float:
        return self.transform.angle_deg()

    def summary(self) -> str:
        return (f"projection difference: rms {self.rms:.3f} px, max {self.max:.3f} px over {self.n} points "
                f"(fitted rotation {self.rotation_deg:.4f} deg)")

    def image(self) -> tuple[np.ndarray, tuple[float, float, float, float]]:
        """The magnitudes on the grid as an image (rows, cols), NaN where no point is, and its
        extent (left, right, bottom, top) in pixels for ``imshow(origin="upper")``."""
        rows, cols = grid_shape(self.size, self.step)
        img = np.full((rows, cols), np.nan)
        c = np.round((self.pixels[:, 0] - self.step / 2) / self.step).astype(int)
        r = np.round((self.pixels[:, 1] - self.step / 2) / self.step).astype(int)
        img[r, c] = self.magnitude
        return img, (0.0, cols * self.step, rows * self.step, 0.0)

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def _within_range(cam: Camera, X: np.ndarray) -> np.ndarray:
    """Whether camera-frame points (N, 3) lie where ``cam`` projects them one to one: finite,
    and the ray's angle from the axis below the model's monotonic limit (which is below 90
    degrees unless the lens is a fisheye)."""
    angle = np.arctan2(np.hypot(X[:, 0], X[:, 1]), X[:, 2])
    ok = np.all(np.isfinite(X), 1) & (angle < cam.lens.max_angle(cam.D))
    if not cam.lens.wide:
        ok &= X[:, 2] > 0
    return ok


def _fit(P: np.ndarray, q: np.ndarray, b: Camera, start: Transform, distance: float | None) -> Transform:
    """Least squares in pixels over the rotation vector (and at a finite range the translation,
    as t = r tau so that both parameters move pixels by about f times themselves)."""
    scale = 1.0 if distance is None else distance

    def transform(x: np.ndarray) -> Transform:
        return Transform.from_rotvec(x[:3], x[3:] * scale if len(x) > 3 else np.zeros(3))

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.asarray((b.project(transform(x).apply(P)) - q).ravel())

    x0 = start.rotvec if distance is None else np.concatenate([start.rotvec, start.translation / scale])
    sol = least_squares(residuals, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200 * len(x0))
    return transform(sol.x)


def projection_difference(a: Camera, b: Camera, region_mask: np.ndarray | None = None,
                          distance: float | None = None, step: float = DEFAULT_STEP) -> ProjectionDiff:
    """Difference of B against A over A's image after the implied transformation A -> B
    (module docstring; mrcal's ``projection_diff``).

    ``region_mask`` (height, width) bool restricts the grid, and so the fit and every number, to
    where it is true (e.g. the observed field of a calibration: a model is only known there);
    ``distance`` is the range in metres (None: infinity, rotation-only fit); ``step`` the grid
    spacing in pixels. Raises :class:`CompareError` if the image sizes differ or fewer than
    three grid points are usable.
    """
    if (a.width, a.height) != (b.width, b.height):
        raise CompareError(f"the calibrations are of different image sizes: {a.width}x{a.height} and "
                           f"{b.width}x{b.height}")
    if a.width <= 0 or a.height <= 0:
        raise CompareError(f"the calibrations have no image size ({a.width}x{a.height})")
    if distance is not None and not (np.isfinite(distance) and distance > 0):
        raise CompareError(f"distance must be a positive number of metres, got {distance}")
    if not step > 0:
        raise CompareError(f"step must be positive, got {step}")
    if region_mask is not None and region_mask.shape != (a.height, a.width):
        raise CompareError(f"the region is {region_mask.shape[1]}x{region_mask.shape[0]}, the images "
                           f"{a.width}x{a.height}")
    q_all = grid_pixels(a.size, step, region_mask)
    rays_a = a.unproject(q_all)
    ok = np.all(np.isfinite(rays_a), 1)
    # start: the rotation that carries A's rays onto B's rays of the same pixels (Wahba's problem)
    rays_b = b.unproject(q_all)
    both = ok & np.all(np.isfinite(rays_b), 1)
    if both.sum() < MIN_POINTS:
        raise CompareError(f"only {int(both.sum())} grid points are inside both models' range")
    rot0, _ = Rotation.align_vectors(rays_b[both], rays_a[both])
    P_all = rays_a if distance is None else distance * rays_a
    T = Transform(rot0)
    # fit on the points B can image; refit if the fit moved some out of (or into) B's range
    use = ok & _within_range(b, T.apply(P_all))
    for _ in range(3):
        if use.sum() < MIN_POINTS:
            raise CompareError(f"only {int(use.sum())} grid points are inside both models' range")
        T = _fit(P_all[use], q_all[use], b, T, distance)
        now = ok & _within_range(b, T.apply(P_all))
        if np.array_equal(use, now):
            break
        use = now
    if use.sum() < MIN_POINTS:
        raise CompareError(f"only {int(use.sum())} grid points are inside both models' range")
    diff = b.project(T.apply(P_all[use])) - q_all[use]
    return ProjectionDiff(q_all[use], diff, T, distance, float(step), a.width, a.height,
                          n_excluded=int(len(q_all) - use.sum()))


@dataclass(frozen=True)
class Region:
    """The observed field of a calibration: the convex hulls of its views (polygons of pixels)."""

    hulls: list[np.ndarray]
    width: int
    height: int

    @property
    def mask(self) -> np.ndarray:
        """(height, width) bool: inside some hull."""
        return hulls_mask(self.hulls, self.size)

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def region_from_report(path: str | Path) -> Region:
    """The observed field stored in a calibration's ``report.json`` (:func:`~..io.report_json.
    read_view_hulls`)."""
    try:
        return Region(*read_view_hulls(path))
    except ReportJsonError as e:
        raise CompareError(str(e)) from None
