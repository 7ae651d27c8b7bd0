"""The detector's bias in an arm's prediction: a systematic error of every view's pose that no
noise covariance shows and that does not average down over a view's points. An option of the
arm guide's model (``arm_model(bias=...)``), off in the product: measured in the guided-sessions
study (docs/guided-sessions.md, "The bias term, built and measured"), it did not improve the
guide's choices beyond noise, so the study keeps it to reproduce that result.

**Measured** (noise-free renders, the arm study's cell: 800x600, ``ring_grid_a4``, blur 1 px,
gamma 2.2; each view's pose fitted with the true intrinsics held, its edge offset free; 41 views
of sizes 0.3-0.7 of the image, tilts 0-45 degrees): the pose's error per camera axis grows
steeply as the imaged circles shrink. Maximum-likelihood fits of a zero-mean normal per axis,
sigma = sigma_8 (axis / 8 px)^p: the rotation 0.0037 deg per axis at a semi-major axis of 8 px
(p = -3.9; on the semi-minor axis the fit is worse by 38 in log-likelihood: a head-on view's
rotation is as biased as a tilted one's of the same size), the translation of the local origin
0.0028 mm across and 0.016 mm along the line of sight at a semi-minor axis of 8 px (p = -3.6,
-4.9). Part of it is common to the views in the camera frame (mean over the views 0.3-0.8 of
the RMS per axis): the blur shifts the edges of a given geometry alike. A bias common to every
view's camera_T_target is a change of X itself (X C = X' C' with C' = D C gives X' = X D^-1), so
that share does not average down with the number of views.

**Model.** Per view v a bias beta_v (camera-frame small rotation, translation) with sigma_v(b)
per component and correlation ``rho`` between views, each component alone. It enters the view's
image rows as a change of its pose parameters, r = J_v M_v beta_v (M_v maps beta to the
parameters: the rotation vector's through W_v^-1, :func:`.guidance.pose_rotation_maps`), so the
sandwich's meat B gains Cov(J^T W r) = (1 - rho) sum_v D_v D_v^T + rho s s^T with D_v =
(J^T W J_v) M_v S_v, S_v = diag(sigma_v) and s = sum_v D_v (J^T W J_v: the columns of the image
rows' normal matrix at view v's parameters). A candidate n adds D_n D_n^T and the cross terms
rho (s D_n^T + D_n s^T). This is first-order propagation of the measurements' covariance
through the estimator (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., ch. 5, "forward
propagation of covariance"), here of a measurement error correlated over a view's rows and
between views.

**Checked at X** (noise-free renders and a perfect arm, so X's true error is the bias alone; the
designed 20 views and five guided 12-view paths of the arm study): with the per-view sigmas as
measured the model's bias share of X's rotation was 1.2x the true errors' RMS (0.0062 against
0.0052 deg; per path 0.0035-0.0088 against 0.0013-0.0092, the smallest on the same path, the
designed 20 overstated: 0.0069 against 0.0030) and of its translation 0.74x (0.051 against
0.069 mm); the defaults are scaled by 0.85 and 1.35 to match.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...calibrate import Problem, ViewData
from ...geometry import ImageSize
from .guidance import (
    ChainRows,
    Linearisation,
    Prediction,
    ViewPredictor,
    candidate_blocks,
    centre_distances,
    pose_rotation_maps,
)


@dataclass(frozen=True)
class DetectorBias:
    """sigma per camera axis of a view's pose bias as powers of its circles' imaged semi-axes
    (module docstring): the rotation (deg) of the semi-major axis a (the circles' apparent size:
    the fit on a explains the renders better than on b, and does not count a tilt against a
    view), the translation across and along the line of sight (mm) of the semi-minor axis b; at
    ``ref_px``, the axes clipped to ``px_range`` (the measured range); ``rho`` the correlation
    between views."""

    rotation_deg: float = 0.0031  # 0.0037 measured per view, x 0.85 (the check at X: module docstring)
    rotation_power: float = -3.9
    across_mm: float = 0.0038  # 0.0028 measured, x 1.35
    across_power: float = -3.6
    along_mm: float = 0.022  # 0.016 measured, x 1.35
    along_power: float = -4.9
    ref_px: float = 8.0
    px_range: tuple[float, float] = (4.5, 14.0)
    rho: float = 0.3

    def sigmas(self, semi_minor: np.ndarray, semi_major: np.ndarray) -> np.ndarray:
        """(V, 6) sigma of (rotation about x, y, z in rad; translation x, y, z in m) per view."""

        def rel(v: np.ndarray) -> np.ndarray:
            v = np.asarray(v, float)
            return np.clip(np.where(np.isfinite(v), v, self.ref_px), *self.px_range) / self.ref_px

        b, a = rel(semi_minor), rel(semi_major)
        r = np.radians(self.rotation_deg) * a ** self.rotation_power
        x = self.across_mm / 1000 * b ** self.across_power
        z = self.along_mm / 1000 * b ** self.along_power
        return np.stack([r, r, r, x, x, z], axis=1)


def semi_axes_px(view: ViewData) -> tuple[float, float]:
    """Medians over a view's circles of the (semi-minor, semi-major) axes (px) of its edge points
    (evenly spread along the arc their covariance has eigenvalues a^2 / 2 and b^2 / 2, as in
    :func:`.guidance.semi_minor_px`); NaN without circles."""
    ids = np.asarray(view.circle_ids)
    if len(ids) == 0:
        return float("nan"), float("nan")
    _, group, n = np.unique(ids, return_inverse=True, return_counts=True)
    pts = np.asarray(view.points, float)
    mean = np.stack([np.bincount(group, pts[:, k]) for k in (0, 1)], 1) / n[:, None]
    d = pts - mean[group]
    a, b, c = (np.bincount(group, d[:, i] * d[:, j]) / n for i, j in ((0, 0), (0, 1), (1, 1)))
    root = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    keep = n >= 4
    if not keep.any():
        return float("nan"), float("nan")
    lo, hi = (np.sqrt(2 * np.maximum(0.5 * (a + c) + sgn * root, 0.0))[keep] for sgn in (-1.0, 1.0))
    return float(np.median(lo)), float(np.median(hi))


DETECTOR_BIAS = DetectorBias()


def bias_maps(prob: Problem, poses: np.ndarray, views: Sequence[ViewData], bias: DetectorBias) -> np.ndarray:
    """(V, per_view, 6) M_v S_v: the change of each view's parameters per sigma of each bias
    component (module docstring; the edge offset untouched)."""
    W, _ = pose_rotation_maps(prob, poses)
    axes = np.array([semi_axes_px(v) for v in views]).reshape(-1, 2)
    S = bias.sigmas(axes[:, 0], axes[:, 1])
    out = np.zeros((len(W), prob.per_view, 6))
    nr = W.shape[2]
    out[:, :nr, :3] = np.linalg.pinv(W)  # rotation parameters per small rotation
    out[:, nr:nr + 3, 3:] = np.eye(3)
    return out * S[:, None, :]


class BiasedPredictor(ViewPredictor):
    """:class:`.guidance.ViewPredictor` whose meat B carries the detector's bias (module
    docstring); ``n_image`` rows of the problem are image rows (the rest, a robot chain's)."""

    def __init__(self, lin: Linearisation, size: ImageSize, n_image: int,
                 bias: DetectorBias = DETECTOR_BIAS):
        super().__init__(lin, size)
        self.bias = bias
        prob = self.prob
        f, Jg, Jv = prob.evaluate(lin.x, lin.intr0)
        w = np.where(np.arange(len(f)) < n_image, lin.w, 0.0)
        A_img, _ = prob.normal_equations(f, Jg, Jv, w)
        maps = bias_maps(prob, prob.unpack(lin.x, lin.intr0)[2], prob.views, bias)
        s = np.zeros((len(A_img), 6))
        ind = np.zeros_like(A_img)
        for v in range(self.nv):
            c = self.ng + v * self.pv
            D = A_img[:, c:c + self.pv] @ maps[v]
            s += D
            ind += D @ D.T
        self.B = self.B + (1 - bias.rho) * ind + bias.rho * s @ s.T
        self.cov_now = self.L @ self.Ainv @ self.B @ self.Ainv @ self.L.T
        self.Q00 = self.Y0.T @ self.B @ self.Y0
        BAE = self.B @ self.AE
        self.Q01 = self.Y0.T @ BAE
        self.Q11 = self.AE.T @ BAE
        self.Ys, self.AEs = self.Y0.T @ s, self.AE.T @ s

    def predict(self, views: Sequence[ViewData], poses: np.ndarray, weights: Sequence[np.ndarray] | None = None,
                coarse: int = 1, chain: ChainRows | None = None) -> Prediction:
        """:meth:`.guidance.ViewPredictor.predict` with each candidate's bias (module docstring)."""
        if len(views) == 0:
            return super().predict(views, poses, weights, coarse, chain)
        poses = np.asarray(poses, float)
        blocks = candidate_blocks(self, views, poses, weights, chain)
        cj = chain.rows(poses) if chain is not None else None
        maps = bias_maps(self.prob, poses, views, self.bias)
        covs = []
        for i, (UA, GA, AA, UB, GB, AB, ln) in enumerate(blocks):
            a_g, a_v = (GA, AA) if cj is None else (GA - cj[0][i].T @ cj[1][i], AA - cj[1][i].T @ cj[1][i])
            d_g, d_v = a_g @ maps[i], a_v @ maps[i]
            covs.append(self._biased_update(UA, GA, AA, UB + d_g @ d_g.T, GB + d_g @ d_v.T, AB + d_v @ d_v.T,
                                            ln, (d_g, d_v)))
        dist = np.median(np.c_[np.tile(self.distances, (len(poses), 1)), centre_distances(self.prob, poses)], axis=1)
        _, G = self.grid_jacobians(coarse)
        sig = np.array([np.max(self.sigma_map(c, d, G)) if len(G) else np.nan for c, d in zip(covs, dist, strict=True)])
        return Prediction(sig, np.stack(covs), dist)

    def _biased_update(self, UA: np.ndarray, GA: np.ndarray, AA: np.ndarray, UB: np.ndarray, GB: np.ndarray,
                       AB: np.ndarray, ln: np.ndarray, d: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """The guidance module's update (Schur complement and Woodbury identity) plus the cross
        terms rho (s D_n^T + D_n s^T) between the candidate's bias and the views' (d: D_n's rows
        on the globals and on the new view)."""
        Mk, Zg, Zn, plain = self._update_terms(UA, GA, AA, UB, GB, AB, ln)
        Zs = self.Ys - Mk.T @ self.AEs  # Z_o^T s (k, 6)
        Dz = d[0].T @ Zg + d[1].T @ Zn  # D_n^T Z' (6, k)
        cross = self.bias.rho * Zs @ Dz
        out = plain + cross + cross.T
        return 0.5 * (out + out.T)
