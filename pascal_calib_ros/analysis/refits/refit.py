"""Refit a camera into another lens model over a region, and say how far the refit is off there.

Consumers that take only plumb_bob (or a pinhole, or radtan without k3, or mrcal's models) need a
richer calibration re-expressed in their model. The refit is a least-squares fit on projected rays:

1. a grid of pixels q_i (every ``FIT_STEP_DIVISOR``-th of the image's larger side) inside the
   region (the observed field of the calibration, from a ``report.json`` / ``calibration.json``
   ``coverage.view_hulls``, or the whole image);
2. each is unprojected by the source camera to a ray v_i;
3. the target model's fx, fy, cx, cy and free coefficients minimise sum_i |project(v_i) - q_i|^2
   (Levenberg-Marquardt with the analytic Jacobian of
   :func:`~..geometry.camera.project_with_jacobians`), skew 0 (no consumer format has one); the
   camera frame is kept: no rotation is fitted, so a hand-eye or rig transform stays valid.

The error is then measured exactly as ``pascal-calib diff`` measures (``projection_difference``
of the source against the refit over the same region, after the best rotation) on a dense grid
(``MEASURE_STEP_DIVISOR``: ``diff --step 4`` at 800x600), so the figure stated is what a user gets
by running diff between the two files at that step, and what any finer grid gives within a few
percent.
The largest displacement without any rotation removed is stated too. A refit whose worst error
exceeds the threshold is refused (:class:`RefitError`) unless forced, with where it fails: the
share of the region above the threshold, the image regions where it lies (3x3 cells) and the
radius from the principal point within which the refit holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from ...errors import PascalCalibError
from ...geometry import DISTORTION_CHOICES, Camera, grid_pixels, project_with_jacobians
from ..statistics.compare import CompareError, ProjectionDiff, projection_difference

DEFAULT_MAX_ERROR_PX = 0.25  # worst projection error over the region a refit may have unless forced
FIT_STEP_DIVISOR = 100  # the fit's grid: the image's larger side / this (px)
# the measurement's grid: the image's larger side / this (px; 4 px at 800x600). A refit's error gathers at the image's
# rim, so a coarse grid (diff's default 16 px, whose outer cell centres lie 8 px inside the border) understates it;
# at this density the figures are those of the continuous field to a few percent
MEASURE_STEP_DIVISOR = 200
PINHOLE_MAX_ANGLE_DEG = 80.0  # an x/z model is not fitted to rays further from the axis than this
CELL_NAMES = (("top-left", "top", "top-right"), ("left", "centre", "right"),
              ("bottom-left", "bottom", "bottom-right"))


class RefitError(PascalCalibError):
    """The camera cannot be refitted into the model asked for, or the refit is too far off."""


@dataclass(frozen=True)
class RefitResult:
    """A refit (module docstring): the refitted camera and its error against the source.

    ``diff``: the source against the refit as ``pascal-calib diff`` measures it; ``frame_max_px``:
    the largest displacement without a rotation removed; ``choice``: the
    :data:`~..geometry.lens.DISTORTION_CHOICES` key fitted; ``region``: words for where."""

    camera: Camera
    source: Camera
    choice: str
    region: str
    diff: ProjectionDiff
    frame_max_px: float
    threshold_px: float
    worst_px: float  # over the grid and the region's boundary pixels
    worst_pixel: tuple[float, float]

    @property
    def rms_px(self) -> float:
        return self.diff.rms

    @property
    def ok(self) -> bool:
        return self.worst_px <= self.threshold_px

    def summary(self) -> str:
        u, v = self.worst_pixel
        return (f"refit {self.source.model} -> {self.choice} over {self.region}: projection error {self.rms_px:.4f} px "
                f"rms, {self.worst_px:.4f} px worst at ({u:.0f}, {v:.0f}) ({self.diff.n} points, measured as "
                f"pascal-calib diff --step {self.diff.step:g}, the worst also over the region's boundary pixels; "
                f"{self.frame_max_px:.4f} px worst without the rotation removed)")

    def where_it_fails(self) -> str:
        """Where the error exceeds the threshold ('' if nowhere)."""
        mag, pix = self.diff.magnitude, self.diff.pixels
        bad = mag > self.threshold_px
        if not bad.any():
            return ""
        w, h = self.source.width, self.source.height
        col = np.minimum((3 * pix[:, 0] / w).astype(int), 2)
        row = np.minimum((3 * pix[:, 1] / h).astype(int), 2)
        cells = []
        for r in range(3):
            for c in range(3):
                sel = bad & (row == r) & (col == c)
                if sel.any():
                    cells.append((float(mag[sel].max()), CELL_NAMES[r][c]))
        cells.sort(reverse=True)
        K = self.source.K
        rad = np.hypot(pix[:, 0] - K[0, 2], pix[:, 1] - K[1, 2])
        holds = float(rad[bad].min())
        return (f"above {self.threshold_px:g} px on {100 * bad.mean():.1f} % of the region: "
                + ", ".join(f"{name} (worst {m:.3f} px)" for m, name in cells)
                + f"; within {self.threshold_px:g} px inside {holds:.0f} px of the principal point")


def _fit(rays: np.ndarray, q: np.ndarray, source: Camera, choice: str) -> Camera:
    """Least squares over fx fy cx cy and the choice's free coefficients (module docstring)."""
    lens, free_d = DISTORTION_CHOICES[choice]
    d_idx = [lens.coefficients.index(n) for n in free_d]
    cols = [0, 1, 2, 3] + [5 + i for i in d_idx]
    K0 = source.K

    def camera(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        K = np.array([[x[0], 0.0, x[2]], [0.0, x[1], x[3]], [0.0, 0.0, 1.0]])
        D = np.zeros(lens.n)
        D[d_idx] = x[4:]
        return K, D

    def residuals(x: np.ndarray) -> np.ndarray:
        K, D = camera(x)
        return np.asarray((project_with_jacobians(rays, K, D, lens)[0] - q).ravel())

    def jacobian(x: np.ndarray) -> np.ndarray:
        K, D = camera(x)
        return np.asarray(project_with_jacobians(rays, K, D, lens)[2][:, :, cols].reshape(-1, len(cols)))

    x0 = np.r_[K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], np.zeros(len(d_idx))]
    if source.model == lens.name:  # start from the source's own coefficients where the model is the same
        x0[4:] = np.asarray(source.D, float)[d_idx]
    sol = least_squares(residuals, x0, jac=jacobian, method="lm", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        max_nfev=200 * len(x0))
    K, D = camera(sol.x)
    return Camera(K, D, source.width, source.height, lens.name)


def boundary_pixels(mask: np.ndarray) -> np.ndarray:
    """The centres (N, 2) of the pixels on the outer boundary of every part of a region (the grid's
    cell centres stay half a step inside it, and a refit's worst error lies on the rim)."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return np.zeros((0, 2))
    return np.concatenate([c.reshape(-1, 2) for c in contours]).astype(float) + 0.5


def worst_with_boundary(source: Camera, cam: Camera, diff: ProjectionDiff, mask: np.ndarray | None
                        ) -> tuple[float, tuple[float, float]]:
    """The worst displacement over the diff's grid and the region's boundary pixels, after the
    diff's rotation, and where it is."""
    full = np.ones((source.height, source.width), bool) if mask is None else mask
    q = np.concatenate([diff.pixels, boundary_pixels(full)])
    P = source.unproject(q)
    ok = np.all(np.isfinite(P), 1)
    d = np.full(len(q), -1.0)
    d[ok] = np.linalg.norm(cam.project(diff.transform.apply(P[ok])) - q[ok], axis=1)
    d[~np.isfinite(d)] = -1.0
    k = int(np.argmax(d))
    return float(d[k]), (float(q[k, 0]), float(q[k, 1]))


def measure_step(camera: Camera) -> float:
    """The grid step (px) a refit's error is measured on (``MEASURE_STEP_DIVISOR``)."""
    return max(1.0, round(max(camera.width, camera.height) / MEASURE_STEP_DIVISOR))


def refit_camera(source: Camera, choice: str, region_mask: np.ndarray | None = None, region: str = "the whole image",
                 threshold_px: float = DEFAULT_MAX_ERROR_PX, force: bool = False) -> RefitResult:
    """Refit ``source`` into the model of a ``--distortion`` choice (``plumb_bob``,
    ``plumb_bob_k3_fixed`` = Kalibr's radtan, ``none`` = pinhole, ``rational_polynomial``, ...)
    over ``region_mask`` ((height, width) bool; None: the whole image), module docstring.

    Raises :class:`RefitError` if the region holds rays the model cannot describe, or (unless
    ``force``) if the worst error exceeds ``threshold_px``."""
    if choice not in DISTORTION_CHOICES:
        raise RefitError(f"unknown model {choice!r}; choose one of {', '.join(DISTORTION_CHOICES)}")
    if region_mask is not None and region_mask.shape != (source.height, source.width):
        raise RefitError(f"the region is {region_mask.shape[1]}x{region_mask.shape[0]}, the camera "
                         f"{source.width}x{source.height}")
    lens = DISTORTION_CHOICES[choice][0]
    step = max(source.width, source.height) / FIT_STEP_DIVISOR
    q = grid_pixels(source.size, step, region_mask)
    rays = source.unproject(q)
    ok = np.all(np.isfinite(rays), 1)
    q, rays = q[ok], rays[ok]
    if len(q) < 10:
        raise RefitError(f"only {len(q)} pixels of {region} have a ray: nothing to fit")
    angle = float(np.degrees(np.arccos(np.clip(rays[:, 2], -1, 1))).max())
    if not lens.wide and angle > PINHOLE_MAX_ANGLE_DEG:
        raise RefitError(f"{region} sees rays up to {angle:.0f} degrees from the axis; a {lens.name} model (x/z) "
                         f"cannot describe rays beyond about {PINHOLE_MAX_ANGLE_DEG:.0f} degrees: restrict the region "
                         "(--region REPORT_JSON) or export a model that can (equidistant, mrcal)")
    return measured_refit(source, _fit(rays, q, source, choice), choice, region_mask, region, threshold_px=threshold_px,
                          force=force, advice="; --region REPORT_JSON fits only the observed field")


def measured_refit(source: Camera, cam: Camera, choice: str, region_mask: np.ndarray | None, region: str, *,
                   threshold_px: float, force: bool, advice: str = "") -> RefitResult:
    """A refit ``cam`` of ``source`` measured as every refit is: its projection difference over the
    region (:func:`~..statistics.compare.projection_difference`), the worst error with the region's
    boundary (:func:`worst_with_boundary`), the largest move of a pixel with no rotation allowed;
    refused above ``threshold_px`` unless ``force`` (``advice`` ends the refusal's hint)."""
    try:
        diff = projection_difference(source, cam, region_mask, step=measure_step(source))
    except CompareError as e:
        raise RefitError(f"the refit cannot be measured over {region}: {e}") from None
    frame = cam.project(source.unproject(diff.pixels)) - diff.pixels
    worst, at = worst_with_boundary(source, cam, diff, region_mask)
    res = RefitResult(camera=cam, source=source, choice=choice, region=region, diff=diff,
                      frame_max_px=float(np.nanmax(np.linalg.norm(frame, axis=1))), threshold_px=threshold_px,
                      worst_px=worst, worst_pixel=at)
    if not res.ok and not force:
        raise RefitError(f"{res.summary()}; {res.where_it_fails()}. Refused: above --max-error {threshold_px:g} px "
                         f"(--force writes it anyway{advice})")
    return res
