"""Cross-validation of a calibration: two independent halves of the views, compared.

After mrcal's "tour of mrcal: cross-validation" (http://mrcal.secretsauce.net/tour-cross-validation.html)
and its differencing (http://mrcal.secretsauce.net/differencing.html). The projection uncertainty
(:mod:`.uncertainty`) only says how much the calibration moves with the noise of the observed
edges; it says nothing about *model errors* (a lens model too simple for the lens, a sheet that
is not flat, a camera or focus that changed between views), which bias the result without
widening its error bars. Two calibrations from disjoint views sample both: if the model holds,
they differ only by their noise, as much as their uncertainties predict; if it does not, each
half fits the model error of its own views differently and they differ by more.

1. The usable views (a target detected) are split into two interleaved halves, A = views 0, 2,
   4, ... and B = views 1, 3, 5, ... among them (interleaved so that a slow drift of the session,
   or the order in which a user swept the image, is shared by both halves), and each half is
   calibrated with the same options.
2. Their projection difference (:func:`.compare.projection_difference`, mrcal's
   ``projection_diff``: B against A after the implied transformation between the two camera
   frames) is taken over the intersection of the halves' observed fields (the union if they do
   not overlap), where both models are known.
3. What the difference should be if only noise separates the halves: each half's parameter
   covariance (the refinement's sandwich covariance, :mod:`.uncertainty`) is propagated to the
   projection of every grid ray at infinity (carried through the views' frames as mrcal does), and
   the part a rotation can absorb is removed, since the difference fits one
   (:func:`~.uncertainty.rotation_free_difference_variance`). The expected RMS is the RMS over the
   same points of sqrt(E|d_A|^2 + E|d_B|^2); the verdict is the ratio observed / expected
   (:data:`AGREE_RATIO`).

Range: the difference is taken at infinity (rays; the fit is a rotation only), as mrcal's
``projection_diff`` does by default. Not at a finite range r: with every grid point at the same
r, project(R r v + t) = project(R v + t / r), so a fitted translation acts at any finite r like a
change of scale along the axis and absorbs most of a focal-length difference, the largest part of
what two halves disagree on. The prediction is made for the same rays and the same fitted
rotation, so observed and expected measure the same thing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...calibrate import CalibrationError, CalibrationOptions, CalibrationResult, calibrate
from ...detect import Detection
from ...targets import Target
from .assessment import assess
from .compare import CompareError, ProjectionDiff, projection_difference
from .uncertainty import rotation_displacements, rotation_free_difference_variance

# The halves agree when their difference is at most this many times what their uncertainties
# predict. The difference is dominated by a few parameters (focal length, k1), so its squared RMS
# scatters like a chi-square with few degrees of freedom around the prediction. Measured on 640x480
# renders (16 views, plumb_bob lenses with k1 0 to -0.3, plumb_bob fits, 8 sessions each): ring_a4
# ratios 0.35-3.2, median 1.1; ring_grid_a4 0.11-0.89 (its sigmas are conservative: README, Trust).
# Model errors: a bent sheet (3 mm) fitted flat, ring grid, 9.9-16x; k1 k2 fitted to a lens with
# p1, p2 of 0.003, -0.002, 3.0-8.1x; no distortion fitted to k1 = -0.1, 2.2-5.8x (a gross misfit
# also widens the halves' own uncertainty, and shows in the edge RMS first).
AGREE_RATIO = 3.0


@dataclass(frozen=True)
class CrossValidation:
    """Two calibrations of disjoint halves of the usable views and how much they differ.

    ``halves``: the calibrations of A and B; ``views``: the view names of each half;
    ``diff``: B against A (:class:`~.compare.ProjectionDiff`) at infinity;
    ``expected``: sqrt(E|d_A|^2 + E|d_B|^2) per point of ``diff.pixels`` (px; module docstring);
    ``region``: where the difference was taken; ``distances``: the range of each half's
    projection-uncertainty map (m); ``hints``: what to try if they disagree.
    """

    halves: tuple[CalibrationResult, CalibrationResult]
    views: tuple[list[str], list[str]]
    diff: ProjectionDiff
    expected: np.ndarray
    region: str
    distances: tuple[float, float]
    hints: tuple[str, ...] = ()

    @property
    def observed_rms(self) -> float:
        return self.diff.rms

    @property
    def expected_rms(self) -> float:
        """RMS of the expected difference over its points (px)."""
        e = self.expected[np.isfinite(self.expected)]
        return float(np.sqrt(np.mean(e ** 2))) if len(e) else float("nan")

    @property
    def ratio(self) -> float:
        """Observed RMS difference / expected RMS (NaN if the uncertainty is unknown)."""
        exp = self.expected_rms
        if not np.isfinite(exp):
            return float("nan")
        return self.observed_rms / exp if exp > 0 else float("inf")

    @property
    def agree(self) -> bool:
        return bool(np.isfinite(self.ratio) and self.ratio <= AGREE_RATIO)

    def summary_line(self) -> str:
        """One line: the halves, where and at what range they were compared, the difference."""
        a, b = self.halves
        return (f"cross-validation: {a.n_used} against {b.n_used} views (interleaved halves), {self.region}, "
                f"at infinity (rays): {self.diff.summary()}")

    @property
    def message(self) -> str:
        """The verdict in words (a user's next step if the halves disagree)."""
        obs, exp, ratio = self.observed_rms, self.expected_rms, self.ratio
        if not np.isfinite(ratio):
            return (f"the two halves differ by {obs:.3f} px rms; their uncertainty is not known, so this cannot be "
                    "judged")
        if self.agree:
            return (f"the two halves agree: they differ by {obs:.3f} px rms, as their uncertainty predicts "
                    f"({exp:.3f} px)")
        times = f"{ratio:.1f}x" if ratio < 10 else f"{ratio:.0f}x"
        causes = ", ".join(self.hints[:-1]) + (", or " if len(self.hints) > 1 else "") + self.hints[-1]
        return (f"the two halves differ by {obs:.3f} px rms, {times} more than their uncertainty predicts "
                f"({exp:.3f} px): {causes}")


def interleaved_halves(dets: list[Detection]) -> tuple[list[int], list[int]]:
    """Indices of the usable detections at even and at odd positions among them."""
    usable = [k for k, d in enumerate(dets) if d.ok]
    return usable[0::2], usable[1::2]


def expected_difference(res_a: CalibrationResult, res_b: CalibrationResult, pixels: np.ndarray) -> np.ndarray:
    """sqrt(E|d_A|^2 + E|d_B|^2) per pixel (N,): the two halves' noise shares of their projection
    difference at infinity after the fitted rotation
    (:func:`~.uncertainty.rotation_free_difference_variance`; rays of A's camera for both)."""
    cam_a = res_a.camera()
    rays = cam_a.unproject(pixels)
    ok = np.all(np.isfinite(rays), 1)
    out = np.full(len(pixels), np.nan)
    H = rotation_displacements(cam_a, rays[ok])
    var = difference_share(res_a, rays[ok], H) + difference_share(res_b, rays[ok], H)
    out[ok] = np.sqrt(np.maximum(var, 0.0))
    return out


def difference_share(res: CalibrationResult, rays: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Per ray (N,): the expected squared length of this calibration's share of a projection
    difference at infinity after the fitted rotation (H: :func:`~.uncertainty.rotation_displacements`
    of the rays). Raises :class:`CalibrationError` without a parameter covariance."""
    ref = res.refinement
    if ref is None or ref.covariance is None or ref.x is None:
        raise CalibrationError("a calibration has no parameter covariance; cannot judge the difference")
    return rotation_free_difference_variance(ref.camera_of, ref.view_poses_of, ref.x, ref.covariance, rays, H)


# the next richer model to try when the halves disagree (none for the richest ones)
RICHER_MODEL = {"none": "plumb_bob", "radial": "plumb_bob", "plumb_bob_k3_fixed": "plumb_bob",
                "plumb_bob": "rational_polynomial"}


def _hints(opt: CalibrationOptions, target: Target) -> tuple[str, ...]:
    """What may cause a disagreement, with what to try for the ones the options leave open."""
    richer = RICHER_MODEL.get(opt.distortion)
    hints = [f"the lens model ({opt.distortion}) may be too simple for this lens (try --distortion {richer}; "
             "node: distortion_model)" if richer else f"the lens model ({opt.distortion}) may not describe this lens"]
    if not opt.target_shape and (target.grids or target.boards):
        hints.append("the target may not be flat (try --target-shape; node: target_shape)")
    else:
        hints.append("the target may not be flat or its print not true to scale")
    hints.append("the camera (focus, zoom) may have changed during the session")
    return tuple(hints)


def cross_validate(dets: list[Detection], target: Target, options: CalibrationOptions) -> CrossValidation:
    """Calibrate two interleaved halves of the usable views and compare them (module docstring).

    Raises :class:`~.pipeline.CalibrationError` if there are fewer than 2 x ``min_views`` usable
    views, if a half cannot be calibrated, or if the options give no projection uncertainty (no
    refinement)."""
    if not options.refine:
        raise CalibrationError("cross-validation compares the halves against their projection uncertainty, which "
                               "needs the refinement (not --no-refine)")
    idx_a, idx_b = interleaved_halves(dets)
    n = len(idx_a) + len(idx_b)
    if n < 2 * options.min_views:
        raise CalibrationError(f"{n} usable view(s); cross-validation needs {2 * options.min_views} (two halves of "
                               f"min_views = {options.min_views})")
    halves = []
    for label, idx in (("A", idx_a), ("B", idx_b)):
        try:
            halves.append(calibrate([dets[k] for k in idx], target, options))
        except CalibrationError as e:
            raise CalibrationError(f"half {label} ({len(idx)} views) cannot be calibrated: {e}") from None
    res_a, res_b = halves
    pa, pb = assess(res_a).projection, assess(res_b).projection
    if pa is None or pb is None:
        raise CalibrationError("a half has no projection uncertainty (no parameter covariance); cannot judge the "
                               "difference")
    mask_a = res_a.observed_field()
    mask_b = res_b.observed_field()
    mask, region = mask_a & mask_b, "common observed field"
    if not mask.any():
        mask, region = mask_a | mask_b, "union of the observed fields (they do not overlap)"
    try:
        diff = projection_difference(res_a.camera(), res_b.camera(), mask, None)
    except CompareError as e:
        raise CalibrationError(f"the halves cannot be compared: {e}") from None
    expected = expected_difference(res_a, res_b, diff.pixels)
    return CrossValidation((res_a, res_b), ([v.name for v in res_a.views], [v.name for v in res_b.views]), diff,
                           expected, region, (pa.distance, pb.distance),
                           _hints(options, target))
