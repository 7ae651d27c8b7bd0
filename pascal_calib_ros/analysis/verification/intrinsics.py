"""Does a calibration still hold? A test of fresh views against the calibration and its uncertainty.

Cameras drift (a knock, a refocus, a warm lens). Fresh views of a target are tested in two steps:

1. **Held fixed**: the calibration (K, D) is held and only each view's target pose (and edge
   offset) is fitted; the edge RMS left is reported (a gross change shows here first).
2. **Freed**: from that solution the intrinsics the calibration estimated (its
   ``distortion_choice``) are freed and refitted on the fresh views alone, with the calibration's
   own machinery (:func:`~..calibrate.refine.refine`: robust loss, sandwich covariance with
   per-view noise and correlated edge residuals). The shift delta = theta_fresh - theta_stored
   is tested against Sigma = Sigma_fresh + Sigma_stored: the fresh estimate's covariance and the
   stored calibration's own (``calibration.json``; without it Sigma_stored = 0 and the text says
   so: a "changed" may then be the calibration's own error). This is the Wald test of "the
   intrinsics are those stored"; holding the calibration and freeing it are the two ends of the
   likelihood-ratio test of the same hypothesis.

The parameters are tested in groups (focal length fx fy; principal point cx cy; skew; the
distortion coefficients; with a hand-eye result, X: :mod:`.verify_hand_eye`): per group
chi^2 = delta_g^T Sigma_g^+ delta_g against the chi-square distribution of rank(Sigma_g) degrees of
freedom, and the calibration has **changed** when some group's p-value is below alpha / (number of
groups) (Bonferroni: the chance of a false "changed" is at most alpha when the sigmas are honest).
The parameters named as moved are those of a changed group whose |z| = |delta_i| / sigma_i exceeds
the same two-sided level (at least the group's largest).

The **projection shift** is the fresh camera against the stored one as ``pascal-calib diff``
measures it (over the whole image, at infinity, after the best rotation), with the RMS that noise
alone would give: Sigma propagated to every grid ray's projection with the part a rotation absorbs
removed (:func:`~..calibrate.uncertainty.rotation_free_difference_variance`'s construction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2, norm

from ...calibrate import RefineResult, intrinsic_names, refine
from ...geometry import DISTORTION_CHOICES, Camera, project_with_jacobians
from ...io import CalibrationRecord
from ..statistics.compare import CompareError, ProjectionDiff, projection_difference
from ..statistics.uncertainty import rotation_displacements
from .fixed_views import FreshViews

DEFAULT_ALPHA = 0.001  # the chance of a false "changed" with honest sigmas (Bonferroni over the groups)
GROUPS = (("focal length", ("fx", "fy")), ("principal point", ("cx", "cy")), ("skew", ("skew",)))


@dataclass(frozen=True)
class ParameterShift:
    name: str
    stored: float
    fresh: float
    sigma_fresh: float
    sigma_stored: float  # 0 when unknown

    @property
    def delta(self) -> float:
        return self.fresh - self.stored

    @property
    def sigma(self) -> float:
        return float(np.hypot(self.sigma_fresh, self.sigma_stored))

    @property
    def z(self) -> float:
        return self.delta / self.sigma if self.sigma > 0 else float("inf") * np.sign(self.delta)


@dataclass(frozen=True)
class GroupTest:
    """One group's chi-square test (module docstring)."""

    name: str
    parameters: tuple[str, ...]
    chi2: float
    dof: int
    p_value: float
    changed: bool


@dataclass(frozen=True)
class IntrinsicCheck:
    """What the fresh views say about the intrinsics (module docstring)."""

    parameters: list[ParameterShift]
    groups: list[GroupTest]
    fresh: Camera
    shift: ProjectionDiff | None  # fresh against stored, as diff measures it
    expected_shift_rms_px: float  # what noise alone gives over the same points
    rms_fixed_px: float  # edge RMS with the calibration held
    rms_free_px: float  # ... with the intrinsics refitted
    stored_covariance: bool
    z_level: float  # |z| above which a parameter of a changed group is named
    refinement: RefineResult = field(repr=False)

    @property
    def moved(self) -> list[ParameterShift]:
        out = []
        for g in self.groups:
            if not g.changed:
                continue
            ps = [p for p in self.parameters if p.name in g.parameters]
            named = [p for p in ps if abs(p.z) >= self.z_level] or [max(ps, key=lambda p: abs(p.z))]
            out += named
        return out


def _aligned_stored_covariance(ref: CalibrationRecord, names: tuple[str, ...]) -> np.ndarray:
    """The stored covariance on ``names`` (rows and columns of names it lacks are zero)."""
    S = np.zeros((len(names), len(names)))
    if ref.covariance is None:
        return S
    idx = {n: i for i, n in enumerate(ref.parameters)}
    have = [(k, idx[n]) for k, n in enumerate(names) if n in idx]
    for a, i in have:
        for b, j in have:
            S[a, b] = ref.covariance[i, j]
    return S


def group_tests(names: tuple[str, ...], delta: np.ndarray, cov: np.ndarray, alpha: float, extra_groups: int = 0
                ) -> list[GroupTest]:
    """The chi-square test of every group present in ``names`` (distortion: the coefficients);
    each at level alpha / (groups + ``extra_groups``), the others tested elsewhere (hand-eye)."""
    groups = [(g, tuple(n for n in ns if n in names)) for g, ns in GROUPS]
    base = {n for _, ns in GROUPS for n in ns}
    groups.append(("distortion", tuple(n for n in names if n not in base)))
    groups = [(g, ns) for g, ns in groups if ns]
    level = alpha / (len(groups) + extra_groups)
    out = []
    for g, ns in groups:
        sel = [names.index(n) for n in ns]
        d, C = delta[sel], cov[np.ix_(sel, sel)]
        w, V = np.linalg.eigh(0.5 * (C + C.T))
        keep = w > max(float(w.max()), 0.0) * 1e-12
        if not keep.any():
            out.append(GroupTest(g, ns, float("inf") if np.any(d != 0) else 0.0, 0, 0.0, bool(np.any(d != 0))))
            continue
        proj = V[:, keep].T @ d
        stat = float(np.sum(proj**2 / w[keep]))
        dof = int(keep.sum())
        p = float(chi2.sf(stat, dof))
        out.append(GroupTest(g, ns, stat, dof, p, p < level))
    return out


def expected_shift_rms(stored: Camera, names: tuple[str, ...], cov: np.ndarray, pixels: np.ndarray) -> float:
    """RMS over ``pixels`` of the projection shift at infinity that a parameter error of covariance
    ``cov`` (over ``names``) leaves after the best rotation (module docstring)."""
    rays = stored.unproject(pixels)
    rays = rays[np.all(np.isfinite(rays), 1)]
    if not len(rays):
        return float("nan")
    cols = [intrinsic_names(stored.lens).index(n) for n in names]
    G = project_with_jacobians(rays, stored.K, stored.D, stored.lens)[2][:, :, cols].reshape(-1, len(cols))
    H = rotation_displacements(stored, rays)
    M = G - H @ np.linalg.lstsq(H, G, rcond=None)[0]
    var = np.sum((M @ cov) * M, axis=1).reshape(-1, 2).sum(1)
    return float(np.sqrt(np.mean(np.maximum(var, 0.0))))


def check_intrinsics(fresh_views: FreshViews, ref: CalibrationRecord, alpha: float = DEFAULT_ALPHA,
                     extra_groups: int = 0) -> IntrinsicCheck:
    """Free the reference's estimated intrinsics on the fresh views (held-fixed poses as the start)
    and test the shift (module docstring); ``extra_groups``: tests made elsewhere that share alpha."""
    cam = ref.camera
    zero_skew = cam.K[0, 1] == 0.0 and "skew" not in ref.parameters
    fv = fresh_views
    res = refine(fv.views, cam.K, cam.D, fv.poses, fv.dof, ref.choice, zero_skew, fv.use_offsets)
    if res.covariance is None or not np.all(np.isfinite(res.K)):
        raise np.linalg.LinAlgError("the fresh views do not determine the intrinsics (singular normal matrix)")
    prob = res.problem
    assert prob is not None and res.x is not None
    names = tuple(prob.names[i] for i in prob.free)
    n = len(names)
    lens = DISTORTION_CHOICES[ref.choice][0]
    all_names = intrinsic_names(lens)
    theta_s = np.r_[cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2], cam.K[0, 1], cam.D]
    theta_f = np.r_[res.K[0, 0], res.K[1, 1], res.K[0, 2], res.K[1, 2], res.K[0, 1], res.D]
    idx = [all_names.index(nm) for nm in names]
    cov_f = np.asarray(res.covariance[:n, :n])
    cov_s = _aligned_stored_covariance(ref, names)
    cov = cov_f + cov_s
    delta = theta_f[idx] - theta_s[idx]
    params = [ParameterShift(nm, float(theta_s[i]), float(theta_f[i]), float(np.sqrt(max(cov_f[k, k], 0.0))),
                             float(np.sqrt(max(cov_s[k, k], 0.0)))) for k, (nm, i) in enumerate(zip(names, idx,
                                                                                                    strict=True))]
    groups = group_tests(names, delta, cov, alpha, extra_groups)
    fresh = Camera(res.K, res.D, cam.width, cam.height, lens.name)
    try:
        shift: ProjectionDiff | None = projection_difference(cam, fresh)
    except CompareError:
        shift = None
    expected = expected_shift_rms(cam, names, cov, shift.pixels) if shift is not None else float("nan")
    return IntrinsicCheck(parameters=params, groups=groups, fresh=fresh, shift=shift, expected_shift_rms_px=expected,
                          rms_fixed_px=fv.rms_fixed, rms_free_px=float(res.rms),
                          stored_covariance=ref.covariance is not None,
                          z_level=float(norm.isf(alpha / (len(groups) + extra_groups) / 2)), refinement=res)
