"""The report's numbers (``report.json``), computed once from an assessed calibration and its
detections: the observed field, residual statistics and the model-bias verdict (:mod:`..analysis`),
the distortion field and where the lens model holds (:mod:`..geometry.model_field`), the projection
uncertainty; the pages (:mod:`.pages`) draw them."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..analysis import (
    Assessment,
    ModelBias,
    Radial,
    Regional,
    ResidualSamples,
    model_bias,
    radial,
    regional,
    residual_samples_of,
    views_per_region,
)
from ..calibrate import CalibrationResult
from ..detect import Detection, feature_points
from ..geometry import (
    ImageSize,
    distortion_field,
    grid_pixels,
    grid_shape,
    model_valid,
    observed_field_mask,
    view_hulls,
)

FIELD_MARGIN = 30.0  # px around the observed field where the distortion field is still drawn


DISTORTION_STEP = 32  # px between arrows of the distortion field


VALID_STEP = 8  # px between samples of the model's valid region


WORST_VIEWS = 3


@dataclass
class ReportData:
    """Everything the pages and the JSON show, computed once."""

    assessment: Assessment
    dets: list[Detection]
    used_names: list[str]  # names of the used views, in the order of res.edge_points
    hulls: list[np.ndarray]
    field: np.ndarray  # (h, w) bool: the observed field
    samples: ResidualSamples
    regional: Regional
    radial: Radial
    bias: ModelBias
    views_per_region: np.ndarray
    dist_uv: np.ndarray  # distortion field over the observed field + FIELD_MARGIN
    dist_disp: np.ndarray
    valid_grid: np.ndarray  # (rows, cols) bool on a VALID_STEP grid: the model holds there
    view_rms: np.ndarray  # RMS of each used view's residual vectors (edges and corners); NaN: none

    @property
    def res(self) -> CalibrationResult:
        return self.assessment.result


def report_data(a: Assessment, dets: list[Detection]) -> ReportData:
    """Compute the report's numbers for an assessed calibration and its detections."""
    res = a.result
    w, h = res.width, res.height
    cam = res.camera()
    pts = res.feature_points()
    if not sum(len(p) for p in pts):  # not refined (closed form only): the used detections' features
        used = {v.name for v in res.views if v.used}
        pts = [feature_points(d) for d in dets if d.name in used]
    field = observed_field_mask(pts, ImageSize(w, h))
    s = residual_samples_of(res)
    reg = regional(s, ImageSize(w, h))
    rad = radial(s, (float(res.K[0, 2]), float(res.K[1, 2])))
    uv, disp = distortion_field(cam, DISTORTION_STEP, mask=res.observed_field(FIELD_MARGIN))
    held = model_valid(cam, uv)  # a fold inside the margin must not set the colour scale either
    uv, disp = uv[held], disp[held]
    valid = model_valid(cam, grid_pixels(ImageSize(w, h), VALID_STEP)).reshape(grid_shape(ImageSize(w, h), VALID_STEP))
    n_views = len(pts)
    sq = np.bincount(s.view, np.sum(s.vectors**2, 1), minlength=n_views)
    cnt = np.bincount(s.view, minlength=n_views)
    return ReportData(assessment=a, dets=dets, used_names=[v.name for v in res.views if v.used][:n_views],
                      hulls=view_hulls(pts), field=field, samples=s, regional=reg, radial=rad,
                      bias=model_bias(reg, rad, ImageSize(w, h), res.model),
                      views_per_region=views_per_region(pts, ImageSize(w, h), reg.grid),
                      dist_uv=uv, dist_disp=disp, valid_grid=valid,
                      view_rms=np.where(cnt > 0, np.sqrt(sq / np.maximum(cnt, 1)), np.nan))


def per_circle_rms(res: CalibrationResult) -> dict[str, float]:
    """RMS edge residual (px) of every circle over all used views, keyed by the circle's feature
    name (``ring/outer``, ``disc_grid[2,5]`` ...) or its index; worst first."""
    if not res.edge_circles or not sum(len(c) for c in res.edge_circles):
        return {}
    ids = np.concatenate(res.edge_circles).astype(int)
    r = np.concatenate(res.edge_residuals)
    count = np.bincount(ids)
    rms = np.sqrt(np.bincount(ids, r * r) / np.maximum(count, 1))
    names = [res.circle_names[c] if c < len(res.circle_names) else str(c) for c in range(len(count))]
    return {names[c]: float(rms[c]) for c in np.argsort(-rms) if count[c]}


def worst_views(d: ReportData, n: int = WORST_VIEWS) -> list[int]:
    """Indices (into the used views) of the ``n`` views with the largest residual RMS."""
    rms = d.view_rms
    return [int(k) for k in np.argsort(-np.nan_to_num(rms, nan=-1.0)) if np.isfinite(rms[k])][:n]


def _histogram(d: ReportData) -> dict[str, Any]:
    """Histogram of the residuals (edge residuals along their normal, corner residual components)
    and the counts a noise of each view's own RMS would give (a mixture of normals)."""
    from scipy.stats import norm

    res = d.res
    parts = [(np.asarray(r, float), v) for v, r in enumerate(res.edge_residuals)]
    parts += [(np.asarray(c, float).ravel(), v) for v, c in enumerate(res.corner_residuals)]
    vals = np.concatenate([p for p, _ in parts]) if parts else np.zeros(0)
    views = np.concatenate([np.full(len(p), v) for p, v in parts]) if parts else np.zeros(0, int)
    # each view's noise: the RMS of its own values
    sig_v = np.array([float(np.sqrt(np.mean(p * p))) if len(p) else 0.0 for p in
                      [vals[views == v] for v in range(len(d.view_rms))]])
    lim = float(np.percentile(np.abs(vals), 99.5)) if len(vals) else 1.0
    edges = np.linspace(-lim, lim, 41)
    counts = np.histogram(vals, edges)[0]
    expected = np.zeros(len(edges) - 1)
    for v, sg in enumerate(sig_v):
        m = int(np.sum(views == v))
        if m and sg > 0:
            expected += m * np.diff(norm.cdf(edges / sg))
    return {"edges_px": np.round(edges, 5).tolist(), "count": counts.tolist(),
            "expected": np.round(expected, 2).tolist(), "expected_from": "each view's own RMS (normal noise)"}


def report_numbers(d: ReportData) -> dict[str, Any]:
    """``report.json``: every number the pages show (keys documented in the README)."""
    res = d.res
    w, h = res.width, res.height
    mag = np.linalg.norm(d.dist_disp, axis=1) if len(d.dist_disp) else np.zeros(1)
    rad = d.radial
    ring_ok = rad.effective > 0
    valid_px = np.repeat(np.repeat(d.valid_grid, VALID_STEP, 0), VALID_STEP, 1)[:h, :w]
    return {
        "image": {"width": w, "height": h},
        "method": res.method, "refined": res.refined, "distortion_model": res.model,
        "distortion_choice": res.distortion_model,
        "K": res.K.tolist(), "D": res.D.tolist(), "std": res.std,
        "rms_px": res.rms, "degeneracy_ratio": res.degeneracy_ratio, "warnings": d.assessment.warnings,
        "views": [{"name": v.name, "used": v.used, "reason": v.reason, "rms_px": v.rms, "edge_offset_px": v.edge_offset,
                   "corners_rejected_by_detector": v.unmeasured_corners, "outliers_rejected": {
                       "edge_points": v.rejected_edges, "corners": v.rejected_corners},
                   **({} if v.board_corners is None else {"board_corners_measured": list(v.board_corners)})}
                  for v in res.views],
        "coverage": {"observed_fraction": float(d.field.mean()),
                     "observed_field": "union over the used views of the convex hull of their feature points",
                     "views_per_region": {"grid": list(d.regional.grid), "count": d.views_per_region.tolist()},
                     "view_hulls": [np.round(x, 2).tolist() for x in d.hulls]},
        "residuals": {
            "convention": "observed minus predicted; edge residuals along the contour's outward normal",
            "per_view_rms_px": [float(np.sqrt(np.mean(r * r))) if len(r) else float("nan")
                                for r in res.edge_residuals],
            "per_view_vector_rms_px": [round(float(x), 5) if np.isfinite(x) else None for x in d.view_rms],
            "worst_views": [d.used_names[k] for k in worst_views(d) if k < len(d.used_names)],
            "per_circle_rms_px": per_circle_rms(res),
            "max_abs_px": float(max((np.max(np.abs(r)) for r in res.edge_residuals if len(r)), default=0.0)),
            "kappa": {"edges": float(d.samples.kappa[~d.samples.is_corner][0]) if (~d.samples.is_corner).any()
                      else 1.0, "corners": float(d.samples.kappa[d.samples.is_corner][0])
                      if d.samples.is_corner.any() else 1.0},
            "regional": d.regional.as_json(),
            "radial": {"ring_edges_px": np.round(rad.edges_px, 2).tolist(),
                       "mean_px": [round(float(m), 5) if ok else None for m, ok in zip(rad.mean, ring_ok, strict=True)],
                       "stderr_px": [round(float(x), 5) if ok else None for x, ok in zip(rad.stderr, ring_ok,
                                                                                        strict=True)],
                       "count": rad.count.tolist(), "about": "principal point"},
            "histogram": _histogram(d),
            "model_bias": d.bias.as_json()},
        "distortion_field": {"over": f"observed field + {FIELD_MARGIN:.0f} px", "step_px": DISTORTION_STEP,
                             "max_px": float(mag.max()), "mean_px": float(mag.mean()),
                             "points": np.round(np.hstack([d.dist_uv, d.dist_disp]), 3).tolist()},
        "lens_model": {"valid_fraction_of_image": float(d.valid_grid.mean()),
                       "observed_field_inside_valid": float(valid_px[d.field].mean()) if d.field.any() else None,
                       "max_angle_deg": float(np.degrees(res.camera().lens.max_angle(res.D))),
                       "valid": "the model is invertible, projects back within 0.05 px and is monotonic in the "
                                "radius"},
        "uncertainty": {"projection": d.assessment.projection_summary(),
                        "projection_over": "observed field, worst-direction sigma (mrcal's projection uncertainty)",
                        "std_model": res.std_model},
        "target_shape": {"estimated": {n: res.shape[n] for n in res.shape_std}, "std": res.shape_std,
                         "change_against_flat_sheet": res.shape_effect} if res.shape else None,
    }


def hand_eye_numbers(he: Any) -> dict[str, Any]:
    """``report.json`` -> ``hand_eye``: X (camera in the parent frame), its sigma and the arm-accuracy
    share of it, the robot error the data imply, and each view's chain disagreement."""
    X = he.hand_eye
    return {"mode": he.mode, "parent_frame_role": he.parent_frame_role,
            "translation_m": X.translation.tolist(), "rotation_xyzw": X.quat.tolist(),
            "translation_std_mm": np.asarray(he.translation_std_mm).tolist(),
            "rotation_std_deg": np.asarray(he.rotation_std_deg).tolist(),
            "arm_accuracy": {"mm": he.arm_accuracy_mm, "length_m": he.arm_accuracy_length,
                             "translation_share_mm": np.asarray(he.arm_share_mm).tolist(),
                             "rotation_share_deg": np.asarray(he.arm_share_deg).tolist()},
            "robot_error_mm": he.robot_error_mm, "robot_error_deg": he.robot_error_deg,
            "views_used": he.views_used, "rms_px": he.rms_px,
            "per_view": [{k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                          for k, v in asdict(pv).items()} for pv in he.per_view]}
