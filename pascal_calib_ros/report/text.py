"""The words a person reads about a calibration: the summary of the CLI and the report, the one-line
answers of the node, the hand-eye summary. Numbers come from :mod:`..analysis` and :mod:`..calibrate`."""

from __future__ import annotations

import textwrap

import numpy as np

from ..analysis import RADIAL_FLOOR_PX, REGIONAL_FLOOR_PX, Assessment
from ..calibrate import CalibrationResult, ViewReport
from ..calibrate.handeye import HandEyeResult
from .numbers import ReportData, per_circle_rms


def projection_line(a: Assessment) -> str:
    """One line for people: 'projection sigma 0.04 px median, 0.2 px worst in the observed field
    (points at 0.40 m, the median distance to the target's centre)'."""
    s = a.projection_summary()
    if s is None or not np.isfinite(s["median_px"]):
        return "projection sigma: not available"
    where = f"points at {s['distance_m']:.2f} m" if np.isfinite(s["distance_m"]) else "points at infinity"
    if a.projection is not None and a.projection.default_distance:
        where += ", the median distance to the target's centre"
    return (f"projection sigma {s['median_px']:.3f} px median, {s['worst_px']:.3f} px worst in the observed "
            f"field ({where})")


def format_summary(a: Assessment) -> str:
    """The calibration as the CLI prints it: every view used or rejected (with why), the method, RMS,
    K and D with their standard deviations, the target shape, the worst circles, every warning."""
    res = a.result
    lines = ["views:"]
    for v in res.views:
        if v.used:
            extra = ""
            if np.isfinite(v.rms):
                extra = (f"edge rms {v.rms:.3f} px, edge offset {v.edge_offset:+.3f} px" if res.edge_count(v)
                         else f"corner rms {v.rms:.3f} px")
            if view_rejections(v):
                extra += f"; {view_rejections(v)}"
            lines.append(f"  used      {v.name}  {extra}")
        else:
            lines.append(f"  rejected  {v.name}  {v.reason}")
    K, D, s = res.K, res.D, res.std

    def pm(name: str, value: float) -> str:
        return f"{value:.3f} +- {s[name]:.3f}" if name in s else f"{value:.3f}"

    lines += [
        f"method: {res.method}{' + refinement' if res.refinement is not None else ''}"
        f"    views used: {res.n_used}/{len(res.views)}",
        f"RMS: {res.rms:.4f} px" + ("  (edge distance)" if any(len(p) for p in res.edge_points)
                                    else "  (corner reprojection)"),
        f"degeneracy ratio: {res.degeneracy_ratio:.4f}  (>= 0.05 good, < 0.01 rejected)"
        if np.isfinite(res.degeneracy_ratio) else "degeneracy ratio: n/a",
        f"fx = {pm('fx', K[0, 0])}   fy = {pm('fy', K[1, 1])}",
        f"cx = {pm('cx', K[0, 2])}   cy = {pm('cy', K[1, 2])}   skew = {K[0, 1]:.4f}",
        f"D {res.model} ({' '.join(res.camera().lens.coefficients)}) = "
        + "  ".join(pm(n, v) for n, v in zip(res.camera().lens.coefficients, D, strict=True)),
    ]
    if res.shape:
        desc = {"pitch_ratio": ("y/x pitch ratio - 1", 100, "%"), "warp_x": ("warp along x", 1000, "mm"),
                "warp_y": ("warp along y", 1000, "mm")}
        parts = []
        for n, value in res.shape.items():
            if n in res.shape_std:
                label, scale, unit = desc[n]
                parts.append(f"{label} {scale * value:+.4f} +- {scale * res.shape_std[n]:.4f} {unit}")
        lines.append("target shape: " + "; ".join(parts))
        lines.append("  against a flat nominal sheet: " + "  ".join(
            f"{k} {res.shape_effect[k]:+.3f}" for k in ("fx", "fy", "cx", "cy"))
            + f"  (edge RMS {res.shape_effect['rms_flat']:.4f} -> {res.rms:.4f} px)")
    if len(res.circle_names) > 2 and res.edge_circles:
        worst = list(per_circle_rms(res).items())[:3]
        lines.append("worst circles (edge RMS over all views): " + ", ".join(f"{k} {v:.3f} px" for k, v in worst))
    lines += [f"warning: {w}" for w in a.warnings]
    return "\n".join(lines)


def _n(n: int, noun: str) -> str:
    return f"{n} {noun}{'s' if n != 1 else ''}"


def view_rejections(view: ViewReport) -> str:
    """'2 corners rejected by the detector (not on a saddle), 1 corner rejected as outliers', or '';
    a marker board's partial view first says how many of its corners it measured."""
    parts = []
    if view.board_corners is not None and view.board_corners[0] < view.board_corners[1]:
        parts.append(f"{view.board_corners[0]} of the board's {view.board_corners[1]} corners measured")
    if view.unmeasured_corners:
        parts.append(f"{_n(view.unmeasured_corners, 'corner')} rejected by the detector (not on a saddle)")
    out = [_n(n, what) for n, what in ((view.rejected_corners, "corner"), (view.rejected_edges, "edge point")) if n]
    if out:
        parts.append(" and ".join(out) + " rejected as outliers")
    return ", ".join(parts)


def summary_line(res: CalibrationResult) -> str:
    """'fx= fy= cx= cy= rms= views= method=' (the node's answer and status)."""
    K = res.K
    return (f"fx={K[0, 0]:.2f} fy={K[1, 1]:.2f} cx={K[0, 2]:.2f} cy={K[1, 2]:.2f} "
            f"rms={res.rms:.3f}px views={res.n_used}/{len(res.views)} method={res.method}")


def summary_lines(d: ReportData, width: int = 88) -> list[str]:
    """The summary page's text: parameters, views, uncertainty, the verdict, every warning; no line
    longer than ``width``."""
    res = d.res
    names = ["fx", "fy", "cx", "cy", *res.camera().lens.coefficients]
    vals = [res.K[0, 0], res.K[1, 1], res.K[0, 2], res.K[1, 2], *res.D]
    lines = [f"{res.width}x{res.height}, {res.model}; method {res.method}{' + refinement' if res.refined else ''}; "
             f"{res.n_used}/{len(res.views)} views used",
             f"{'edge' if any(len(p) for p in res.edge_points) else 'corner'} RMS {res.rms:.4f} px; "
             f"degeneracy ratio {res.degeneracy_ratio:.3f}",
             projection_line(d.assessment),
             f"observed field: {100 * d.field.mean():.0f} % of the image", ""]
    lines += [f"{n:>3} = {v:12.5f}  +- {res.std.get(n, float('nan')):.5f}" for n, v in zip(names, vals, strict=True)]
    lines.append("")
    b = d.bias
    if b.detected:
        lines += textwrap.wrap("MODEL BIAS: " + b.hint, width)
    else:
        lines += textwrap.wrap(f"model fits: no residual pattern beyond the noise (largest regional mean "
                               f"{b.max_regional_px:.3f} px; floors {REGIONAL_FLOOR_PX} px regional, "
                               f"{RADIAL_FLOOR_PX} px radial)", width)
    lines.append("")
    trimmed = [v for v in res.views if v.used and view_rejections(v)]
    if trimmed:
        lines.append(f"observations left out ({len(trimmed)} views):")
        lines += [f"  {v.name}: {view_rejections(v)}" for v in trimmed[:8]]
        lines.append("")
    lines += textwrap.wrap(f"standard deviations: {res.std_model}", width)
    lines.append("")
    rejected = [v for v in res.views if not v.used]
    if rejected:
        lines.append(f"rejected views ({len(rejected)}):")
        lines += [f"  {v.name}: {v.reason}" for v in rejected[:12]]
        lines.append("")
    others = [x for x in res.warnings if x != b.hint]  # the verdict is said above
    lines += ["warnings:" if others else "no other warnings"]
    for x in others:
        lines += textwrap.wrap(x, width, initial_indent="- ", subsequent_indent="  ")
    # every line within the width (a panel cuts what runs past its edge): long ones wrap, indented
    return [w for line in lines
            for w in textwrap.wrap(line, width, subsequent_indent=" " * (len(line) - len(line.lstrip()) + 4),
                                   drop_whitespace=False) or [line]]


def hand_eye_summary(he: HandEyeResult) -> str:
    """The hand-eye result as the CLI prints it and the report's page shows it."""
    X = he.hand_eye
    t, q = X.translation, X.quat
    s_t, s_r = he.translation_std_mm, he.rotation_std_deg
    rpy = X.rotation.as_euler("xyz", degrees=True)
    lines = [f"hand-eye ({he.mode}): camera in the {he.parent_frame_role} frame",
             "  translation [m]  " + "  ".join(f"{v:+.5f} +- {1e-3 * s:.5f}" for v, s in zip(t, s_t, strict=True)),
             "  rotation [qx qy qz qw]  " + " ".join(f"{v:+.7f}" for v in q),
             "  rotation rpy [deg]  " + " ".join(f"{v:+.4f}" for v in rpy)
             + "   std about x y z [deg]  " + " ".join(f"{v:.4f}" for v in s_r),
             f"  target in the {'base' if he.mode == 'eye_in_hand' else 'tool'} frame: "
             f"t = [{', '.join(f'{v:+.5f}' for v in he.target.translation)}] m",
             (f"  of the std, the arm's assumed systematic error ({he.arm_accuracy_mm:g} mm over "
              f"{he.arm_accuracy_length:g} m): " + " ".join(f"{v:.3f}" for v in he.arm_share_mm) + " mm, "
              + " ".join(f"{v:.4f}" for v in he.arm_share_deg) + " deg"
              if he.arm_accuracy_mm > 0 else "  std without the arm's systematic error (arm accuracy 0)"),
             f"views used: {he.views_used}/{len(he.per_view)}   RMS {he.rms_px:.4f} px   "
             f"robot pose error the data imply: {he.robot_error_mm:.3f} mm, {he.robot_error_deg:.4f} deg "
             "per axis",
             "per view (chain vs images):"]
    for v in he.per_view:
        if v.used:
            lines.append(f"  used      {v.name}  {v.disagreement_mm:.3f} mm  {v.disagreement_deg:.4f} deg")
        else:
            extra = (f"  ({v.disagreement_mm:.1f} mm, {v.disagreement_deg:.2f} deg)"
                     if np.isfinite(v.disagreement_mm) else "")
            lines.append(f"  rejected  {v.name}  {v.reason}{extra}")
    lines += [f"warning: {w}" for w in he.warnings]
    return "\n".join(lines)
