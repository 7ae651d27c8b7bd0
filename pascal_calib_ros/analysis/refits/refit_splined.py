"""Refit a camera (a fisheye: mrcal has no equidistant model) into mrcal's splined stereographic
model (:mod:`~..io.mrcal_splined`), with its error measured as :mod:`.refit` measures every refit.

The knot grid is laid over the whole image (so the exported model is defined wherever a pixel is):
fov_x_deg is the horizontal field of the image's rays in the stereographic plane (whole degrees, as
mrcal's configuration holds it, plus a margin), Nx = :data:`NX` knots across, Ny as many as the
image's vertical extent needs at the same spacing. fx fy cx cy are the source's (the spline absorbs
the difference between its radial law and the stereographic one), and the control values follow
by linear least squares on the region's grid of rays (the correction is linear in them), with a
small second-difference penalty that continues the surface smoothly over knots the region does not
reach.
"""

from __future__ import annotations

import numpy as np

from ...geometry import Camera, grid_pixels
from ...io import SplinedModel, design_matrix, splined_camera, stereographic
from .refit import DEFAULT_MAX_ERROR_PX, FIT_STEP_DIVISOR, RefitError, RefitResult, measured_refit

NX = 24  # knots across the image
FOV_MARGIN_DEG = 4  # degrees added to the image's horizontal field
SMOOTHING = 1e-6  # weight of the second-difference penalty against the data (per unit of A^T A's mean diagonal)
CHOICE = "mrcal_splined"


def _grid_shape(source: Camera) -> tuple[int, int, int]:
    """(Nx, Ny, fov_x_deg) covering the whole image (module docstring)."""
    w, h = source.width, source.height
    cx, cy = source.K[0, 2], source.K[1, 2]
    border = np.concatenate([np.stack([np.linspace(0, w, 200), np.full(200, y)], 1) for y in (0.0, h)]
                            + [np.stack([np.full(200, x), np.linspace(0, h, 200)], 1) for x in (0.0, w)]
                            + [np.array([[cx, 0.0], [cx, h], [0.0, cy], [w, cy]])])
    rays = source.unproject(border)
    rays = rays[np.all(np.isfinite(rays), 1) & (rays[:, 2] > -0.99)]
    if not len(rays):
        raise RefitError("no border pixel of the image has a ray: cannot lay the splined model's knots")
    u = np.abs(stereographic(rays))
    fov = int(np.ceil(np.degrees(4 * np.arctan(u[:, 0].max() / 2)))) + FOV_MARGIN_DEG
    if fov >= 360:
        raise RefitError("the image's field is too wide for mrcal's splined model")
    s = SplinedModel.segments_per_u(NX, fov)
    ny = max(4, int(np.ceil(2 * u[:, 1].max() * s)) + 4)
    return NX, ny, fov


def _second_differences(nx: int, ny: int) -> np.ndarray:
    """Rows of the second differences along x and along y of a (ny, nx) grid flattened row by row."""
    rows = []
    for j in range(ny):
        for i in range(1, nx - 1):
            r = np.zeros(nx * ny)
            r[j * nx + i - 1], r[j * nx + i], r[j * nx + i + 1] = 1, -2, 1
            rows.append(r)
    for j in range(1, ny - 1):
        for i in range(nx):
            r = np.zeros(nx * ny)
            r[(j - 1) * nx + i], r[j * nx + i], r[(j + 1) * nx + i] = 1, -2, 1
            rows.append(r)
    return np.array(rows)


def refit_splined(source: Camera, region_mask: np.ndarray | None = None, region: str = "the whole image",
                  threshold_px: float = DEFAULT_MAX_ERROR_PX, force: bool = False) -> RefitResult:
    """Refit ``source`` into mrcal's splined stereographic model over the region (module docstring);
    the result's ``camera`` is a :class:`SplinedCamera`. Raises :class:`~.refit.RefitError` as
    :func:`~.refit.refit_camera` does."""
    nx, ny, fov = _grid_shape(source)
    q = grid_pixels(source.size, max(source.width, source.height) / FIT_STEP_DIVISOR, region_mask)
    rays = source.unproject(q)
    ok = np.all(np.isfinite(rays), 1)
    q, rays = q[ok], rays[ok]
    if len(q) < 10:
        raise RefitError(f"only {len(q)} pixels of {region} have a ray: nothing to fit")
    fx, fy, cx, cy = source.K[0, 0], source.K[1, 1], source.K[0, 2], source.K[1, 2]
    u = stereographic(rays)
    target = np.stack([(q[:, 0] - cx) / fx, (q[:, 1] - cy) / fy], -1) - u
    A = design_matrix((nx, ny, fov), u)
    N = A.T @ A
    L = _second_differences(nx, ny)
    lam = SMOOTHING * float(np.mean(np.diag(N)))
    ctrl = np.linalg.solve(N + lam * (L.T @ L), A.T @ target)  # (nx ny, 2)
    model = SplinedModel(nx, ny, fov, np.r_[fx, fy, cx, cy, ctrl.ravel()], source.width, source.height)
    return measured_refit(source, splined_camera(model), model.lensmodel, region_mask, region,
                          threshold_px=threshold_px, force=force)
