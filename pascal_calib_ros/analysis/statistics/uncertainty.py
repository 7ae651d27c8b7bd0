"""How far a calibration can be trusted: honest parameter covariances and projection uncertainty.

- **Parameter covariance**: the M-estimator's sandwich over groups of correlated residuals,
  :mod:`..calibrate.covariance` (its docstring has the math and the sources).
- **Projection uncertainty** (mrcal, "Projection uncertainty"): the pixel of a point at a given
  range is uncertain through the intrinsics *and* through the camera's placement relative to the
  views, which the calibration estimates jointly. As mrcal does, the point is carried into every
  view's target frame, back through that view's perturbed pose, averaged over views and projected
  with the perturbed intrinsics; its 2x2 covariance G Sigma G^T (G by central differences over the
  parameters) gives the worst-direction standard deviation sqrt(lambda_max).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ...geometry import ImageSize, grid_pixels, grid_shape

if TYPE_CHECKING:
    from ...calibrate import RefineResult
    from ...geometry import Camera


def _jacobian(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Central differences of a vector function f(x) (M,) over the named columns of x: (M, K)."""
    G = np.zeros((len(f(x)), len(columns)))
    for k, j in enumerate(columns):
        h = 1e-6 * max(abs(float(x[j])), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        G[:, k] = (f(xp) - f(xm)) / (2 * h)
    return G


@dataclass
class ProjectionUncertainty:
    """Worst-direction pixel standard deviation of projecting a point at ``distance`` metres."""

    pixels: np.ndarray  # (N, 2) grid over the image
    sigma: np.ndarray  # (N,) px; NaN where the model cannot unproject
    distance: float  # m (inf: at infinity)
    grid_shape: tuple[int, int]  # (rows, cols) of the grid
    default_distance: bool = False  # the distance is the default (median distance to the target's centre)

    def over(self, mask: np.ndarray | None) -> np.ndarray:
        """The finite sigmas of the grid points inside ``mask`` ((H, W) bool; None: all)."""
        s = self.sigma
        if mask is not None:
            u = np.clip(self.pixels[:, 0].astype(int), 0, mask.shape[1] - 1)
            vv = np.clip(self.pixels[:, 1].astype(int), 0, mask.shape[0] - 1)
            s = s[mask[vv, u]]
        return s[np.isfinite(s)]

    def summary(self, mask: np.ndarray | None) -> dict[str, float]:
        s = self.over(mask)
        if not len(s):
            return {"median_px": float("nan"), "worst_px": float("nan"), "distance_m": self.distance}
        return {"median_px": float(np.median(s)), "worst_px": float(np.max(s)), "distance_m": self.distance}


def projection_uncertainty(camera_of: Callable[[np.ndarray], Camera],
                           view_poses_of: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                           x: np.ndarray, cov: np.ndarray, size: ImageSize, distance: float,
                           step: float | None = None) -> ProjectionUncertainty:
    """mrcal's projection uncertainty (module docstring) on a grid of pixels.

    ``camera_of(x)`` is the camera of a parameter vector, ``view_poses_of(x)`` the views' poses
    (R (V, 3, 3) target -> camera, t (V, 3)); ``cov`` the parameters' covariance. An infinite
    ``distance`` projects directions: the rays are carried through the views' rotations only."""
    width, height = size
    step = step or max(width, height) / 40.0
    uv = grid_pixels(size, step)
    cam = camera_of(x)
    rays = cam.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    finite = bool(np.isfinite(distance))
    p_cam = distance * rays[ok] if finite else rays[ok]
    R, t = view_poses_of(x)
    t0 = t if finite else np.zeros_like(t)
    p_loc = np.einsum("vji,vnj->vni", R, p_cam[None, :, :] - t0[:, None, :])  # R^T (p - t), per view

    def q(xx: np.ndarray) -> np.ndarray:
        Rx, tx = view_poses_of(xx)
        p = np.mean(p_loc @ np.transpose(Rx, (0, 2, 1)), axis=0)  # mean_i R_i p_i (+ t_i)
        if finite:
            p = p + np.mean(tx, axis=0)
        return camera_of(xx).project(p)

    active = np.flatnonzero(np.diag(cov) > 0)
    G = _jacobian(lambda xx: q(xx).reshape(-1), x, active).reshape(len(p_cam), 2, len(active))
    C = (G @ cov[np.ix_(active, active)]) @ np.transpose(G, (0, 2, 1))  # G Sigma G^T per point
    lam = np.linalg.eigvalsh(0.5 * (C + np.transpose(C, (0, 2, 1))))[:, -1]
    sigma = np.full(len(uv), np.nan)
    sigma[ok] = np.sqrt(np.maximum(lam, 0.0))
    return ProjectionUncertainty(uv, sigma, float(distance), grid_shape(size, step))


def rotation_free_difference_variance(camera_of: Callable[[np.ndarray], Camera],
                                      view_poses_of: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                                      x: np.ndarray, cov: np.ndarray, rays: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Per point (N,): the expected squared length of one calibration's share of a projection
    difference at infinity after the best-fitting rotation is removed (mrcal's projection_diff).

    A ray v at infinity is carried into the views' frames and back (mrcal's mean over frames:
    p = mean_i R_i(x) R_i(x0)^T v) and projected: q(x), with Jacobian G (2N x P) by central
    differences. The rotation fitted jointly over all points removes the part of G dx in the span
    of H (2N x 3, the displacement of every point per small rotation), so what remains is
    M dx with M = (I - H H^+) G, of covariance M Sigma M^T; its 2x2 diagonal blocks' traces are
    returned."""
    R0, _ = view_poses_of(x)
    loc = np.einsum("vji,nj->vni", R0, rays)  # R_i^T v

    def q(xx: np.ndarray) -> np.ndarray:
        Rx, _ = view_poses_of(xx)
        return camera_of(xx).project(np.mean(loc @ np.transpose(Rx, (0, 2, 1)), axis=0)).reshape(-1)

    active = np.flatnonzero(np.diag(cov) > 0)
    G = _jacobian(q, x, active)
    M = G - H @ np.linalg.lstsq(H, G, rcond=None)[0]
    per_row = np.sum((M @ cov[np.ix_(active, active)]) * M, axis=1)
    return per_row.reshape(-1, 2).sum(1)


def rotation_displacements(camera: Camera, rays: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """H (2N x 3): d project(R(w) v) / d w at w = 0 for rays v (N, 3), by central differences."""
    return _jacobian(lambda w: camera.project(Rotation.from_rotvec(w).apply(rays)).reshape(-1), np.zeros(3),
                     np.arange(3))


def projection_uncertainty_of(ref: RefineResult, size: ImageSize, distance: float | None = None
                              ) -> ProjectionUncertainty:
    """:func:`projection_uncertainty` of a refinement at ``distance`` metres (default: the median
    distance from the camera to the observed target's centre, ``RefineResult.target_distance``;
    inf: at infinity)."""
    assert ref.x is not None and ref.covariance is not None
    d = ref.target_distance() if distance is None else distance
    out = projection_uncertainty(ref.camera_of, ref.view_poses_of, ref.x, ref.covariance, size, d)
    out.default_distance = distance is None
    return out
