"""Where a camera model holds: rays that project back where they came from, and the distortion field.

- A model is valid at a pixel when it unprojects it to a ray that projects back within a tolerance
  and is monotonic in the radius there (a polynomial fitted beyond its field folds over).
- The distortion field: where the ideal model of the same lens family (same K, no coefficients:
  the pinhole for plumb_bob and rational_polynomial, r = f theta for equidistant) would image each
  ray, against where the calibrated model images it."""

from __future__ import annotations

import numpy as np

from .camera import Camera
from .image_field import grid_pixels


def distortion_field(cam: Camera, step: int = 32, mask: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Grid of pixels (N, 2) (inside ``mask`` if given) and the displacement (N, 2) from where the
    ideal model of the lens family would image each pixel's ray to the pixel itself; rows whose
    ray the model cannot invert are left out."""
    uv = grid_pixels(cam.size, step, mask)
    if not len(uv):
        return uv, np.zeros((0, 2))
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not cam.lens.wide:
        ok &= rays[:, 2] > 1e-6
    ideal = Camera(cam.K, np.zeros(cam.lens.n), cam.width, cam.height, cam.model).project(rays[ok])
    return uv[ok], uv[ok] - ideal


def model_valid(cam: Camera, uv: np.ndarray, tolerance: float = 0.05) -> np.ndarray:
    """(N,) bool: pixels where the lens model holds as a camera model: its ray exists (the model
    is invertible there), projects back onto the pixel within ``tolerance`` px, and lies inside
    the angle up to which the model's radius grows monotonically (``LensModel.max_angle``)."""
    ok, rays = consistent_rays(cam, uv, tolerance)
    if ok.any():
        r = rays[ok] / np.linalg.norm(rays[ok], axis=1, keepdims=True)
        ok[ok] &= np.arccos(np.clip(r[:, 2], -1, 1)) <= cam.lens.max_angle(cam.D)
    return ok


def consistent_rays(cam: Camera, uv: np.ndarray, tolerance: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """(N,) bool and the rays (N, 3): pixels whose ray exists (in front of a pinhole camera) and
    projects back onto the pixel within ``tolerance`` px; where a fitted model folds over, this fails."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    if not len(uv):
        return np.zeros(0, bool), np.zeros((0, 3))
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not cam.lens.wide:
        ok &= rays[:, 2] > 0
    if ok.any():
        ok[ok] &= np.linalg.norm(cam.project(rays[ok]) - uv[ok], axis=1) < tolerance
    return ok, rays
