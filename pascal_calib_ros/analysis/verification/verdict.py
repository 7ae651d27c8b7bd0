"""One verification: fresh detections against a calibration (and a hand-eye result) -> a verdict
with its numbers and its text (:mod:`.verify`, :mod:`.verify_hand_eye`).

The one function both the CLI (``pascal-calib verify``) and the node (``~/verify``) call:
:func:`verify_calibration` takes the detections of the fresh views, the target, the calibration
under test (:class:`~..io.calibration_json.CalibrationRecord`) and, for a hand-eye check, the robot pose of every
detection and the stored hand-eye result; it returns a :class:`Verification` whose
:meth:`~Verification.text` is what a person reads and :meth:`~Verification.as_json` every number.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...calibrate import CalibrationOptions
from ...detect import Detection, DetectionRefusal
from ...geometry import Transform
from ...io import CalibrationRecord
from ...targets import Target
from .fixed_views import FreshViews, VerifyError, fit_fresh_views
from .hand_eye import HandEyeCheck, HandEyeReference, check_hand_eye
from .intrinsics import DEFAULT_ALPHA, IntrinsicCheck, check_intrinsics

HOLDS, CHANGED = "holds", "changed"


@dataclass(frozen=True)
class Verification:
    """The verdict and what it rests on."""

    verdict: str  # HOLDS or CHANGED
    intrinsics: IntrinsicCheck
    hand_eye: HandEyeCheck | None
    fresh: FreshViews
    alpha: float
    warnings: list[str] = field(default_factory=list)

    @property
    def moved(self) -> list[str]:
        """Names of what moved: intrinsics, and 'hand-eye X' when X has."""
        out = [p.name for p in self.intrinsics.moved]
        if self.hand_eye is not None and self.hand_eye.changed:
            out.append("hand-eye X")
        return out

    def text(self) -> str:
        return "\n".join(verification_lines(self))

    def as_json(self) -> dict[str, Any]:
        return verification_json(self)


def verify_calibration(dets: Sequence[Detection], target: Target, reference: CalibrationRecord,
                       robot_poses: Sequence[Transform | None] | None = None,
                       hand_eye: HandEyeReference | None = None, alpha: float = DEFAULT_ALPHA,
                       options: CalibrationOptions = CalibrationOptions()  # noqa: B008 (frozen dataclass)
                       ) -> Verification:
    """Test fresh views against a calibration (and a hand-eye result): module docstring.

    ``robot_poses[i]``: T_base_tool at detection i (None: the view is not used for the hand-eye
    check); needed with ``hand_eye``. Raises :class:`~.verify_views.VerifyError` when the views
    cannot test it (too few, another image size, too few with a robot pose)."""
    if not (0 < alpha < 1):
        raise VerifyError(f"alpha must be between 0 and 1, got {alpha}")
    if hand_eye is not None and (robot_poses is None or len(robot_poses) != len(dets)):
        raise VerifyError("a hand-eye check needs one robot pose (or None) per view")
    dets = list(dets)
    if hand_eye is not None and robot_poses is not None:
        from dataclasses import replace

        dets = [d if p is not None or not d.ok else replace(d, reason="no robot pose for this view",

                                                               refusal=DetectionRefusal.NO_ROBOT_POSE)
                for d, p in zip(dets, robot_poses, strict=True)]
    fv = fit_fresh_views(dets, target, reference.camera, options)
    warnings = []
    if reference.covariance is None:
        warnings.append("the calibration's own uncertainty is unknown (no calibration.json with its covariance): the "
                        "test counts only the fresh views' noise, so a 'changed' may be the calibration's own error")
    try:
        intr = check_intrinsics(fv, reference, alpha, extra_groups=1 if hand_eye is not None else 0)
    except np.linalg.LinAlgError as e:
        raise VerifyError(f"the fresh views cannot re-estimate the intrinsics: {e}; take views tilted in several "
                          "directions and spread over the image") from None
    he = None
    if hand_eye is not None:
        assert robot_poses is not None
        poses = [robot_poses[k] for k in fv.used]
        level = alpha / (len(intr.groups) + 1)
        he = check_hand_eye(fv, [p for p in poses if p is not None], reference.camera, reference.choice, hand_eye,
                            target, level)
    changed = any(g.changed for g in intr.groups) or (he is not None and he.changed)
    return Verification(CHANGED if changed else HOLDS, intr, he, fv, alpha, warnings)


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def verification_lines(v: Verification) -> list[str]:
    """What a person reads: the verdict first, then what it rests on."""
    ic, fv = v.intrinsics, v.fresh
    n_all = len(fv.reports)
    lines = []
    if v.verdict == CHANGED:
        what = [f"{g.name} (p = {g.p_value:.1e})" for g in ic.groups if g.changed]
        if v.hand_eye is not None and v.hand_eye.changed:
            what.append(f"hand-eye X (p = {v.hand_eye.p_value:.1e})")
        moved = ", ".join(f"{p.name} {p.delta:+.4g} ({p.z:+.1f} sigma)" for p in ic.moved)
        lines.append(f"verdict: CHANGED: {', '.join(what)}" + (f"; moved: {moved}" if moved else ""))
    else:
        lines.append(f"verdict: HOLDS (no test below p = {v.alpha:g} over the groups)")
    lines.append(f"views: {len(fv.used)} of {n_all} used; edge RMS {ic.rms_fixed_px:.4f} px with the calibration held, "
                 f"{ic.rms_free_px:.4f} px with the intrinsics refitted")
    lines += [f"  rejected  {n}  {r}" for n, ok, r in fv.reports if not ok]
    lines.append("parameter        stored          fresh          delta    sigma        z")
    for p in ic.parameters:
        lines.append(f"  {p.name:<6} {p.stored:>14.6g} {p.fresh:>14.6g} {p.delta:>+14.4g} {p.sigma:>8.3g} {p.z:>+8.2f}")
    lines.append("groups: " + "; ".join(f"{g.name} chi2 {g.chi2:.1f} ({g.dof} dof) p = {g.p_value:.2g}"
                                        for g in ic.groups))
    if ic.shift is not None:
        lines.append(f"projection shift (fresh against stored, as pascal-calib diff: whole image, at infinity, after "
                     f"the best rotation): {ic.shift.rms:.3f} px rms, {ic.shift.max:.3f} px max; noise alone "
                     f"{ic.expected_shift_rms_px:.3f} px rms")
    he = v.hand_eye
    if he is not None:
        def vec(a: np.ndarray, fmt: str) -> str:
            return "[" + " ".join(format(float(x), fmt) for x in a) + "]"

        lines.append(f"hand-eye: X moved {he.translation_mm:.3f} mm, {he.rotation_deg:.4f} deg (translation "
                     f"{vec(he.delta_mm, '+.3f')} mm, sigma {vec(he.sigma_mm, '.3f')}; rotation "
                     f"{vec(he.delta_deg, '+.4f')} deg, sigma {vec(he.sigma_deg, '.4f')}); z {vec(he.z, '+.1f')}, "
                     f"chi2 {he.chi2:.1f} (6 dof) p = {he.p_value:.2g}: {'CHANGED' if he.changed else 'holds'}")
    lines += [f"warning: {w}" for w in v.warnings]
    return lines


def verification_json(v: Verification) -> dict[str, Any]:
    ic, fv = v.intrinsics, v.fresh
    out: dict[str, Any] = {
        "verdict": v.verdict, "moved": v.moved, "alpha": v.alpha,
        "projection_shift_px": {"rms": _finite(ic.shift.rms) if ic.shift else None,
                                "max": _finite(ic.shift.max) if ic.shift else None,
                                "expected_rms_from_noise": _finite(ic.expected_shift_rms_px),
                                "measured_as": "pascal-calib diff: fresh against stored over the whole image, at "
                                               "infinity, after the best rotation"},
        "parameters": [{"name": p.name, "stored": p.stored, "fresh": p.fresh, "delta": p.delta, "sigma": p.sigma,
                        "sigma_fresh": p.sigma_fresh, "sigma_stored": p.sigma_stored, "z": _finite(p.z)}
                       for p in ic.parameters],
        "groups": [{"name": g.name, "parameters": list(g.parameters), "chi2": _finite(g.chi2), "dof": g.dof,
                    "p_value": g.p_value, "changed": g.changed} for g in ic.groups],
        "stored_covariance": ic.stored_covariance,
        "rms_fixed_px": _finite(ic.rms_fixed_px), "rms_free_px": _finite(ic.rms_free_px),
        "views": [{"name": n, "used": ok, "reason": r} for n, ok, r in fv.reports],
        "views_used": len(fv.used), "warnings": v.warnings, "hand_eye": None,
    }
    he = v.hand_eye
    if he is not None:
        out["hand_eye"] = {"changed": he.changed, "p_value": he.p_value, "chi2": he.chi2,
                           "translation_mm": he.translation_mm, "rotation_deg": he.rotation_deg,
                           "delta_translation_mm": he.delta_mm.tolist(), "delta_rotation_deg": he.delta_deg.tolist(),
                           "sigma_translation_mm": he.sigma_mm.tolist(), "sigma_rotation_deg": he.sigma_deg.tolist(),
                           "z": he.z.tolist(), "X_fresh": {"translation": he.X_fresh.translation.tolist(),
                                                           "rotation_xyzw": he.X_fresh.quat.tolist()},
                           "robot_error_mm": he.robot_error_mm, "robot_error_deg": he.robot_error_deg}
    return out
