"""Checks of a refined calibration: the principal point inside the image, a pinhole model not asked
to describe rays near 90 degrees, a fitted model that does not fold over inside the observed field,
and what the estimated target shape means."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ...detect import Detection
from ...geometry import Camera, ImageSize, LensModel, consistent_rays
from ...targets import Target
from ..solver.refine import RefineResult
from .plumbline import equidistant_focal, has_straight_rows
from .result import CalibrationError


def shape_warnings(shape: dict[str, float], std: dict[str, float], effect: dict[str, float],
                    res: RefineResult) -> list[str]:
    """Say when the estimated shape matters: significant (> 3 sigma) and moving an intrinsic by
    more than its own standard deviation."""
    out = []
    if "pitch_ratio" in std and abs(res.pitch_aspect_correlation) > 0.9:
        out.append(f"the pitch ratio and fy/fx are {abs(res.pitch_aspect_correlation):.2f} correlated: these views "
                   "cannot tell a print scaled in y from non-square pixels; tilt the target more about both axes, or "
                   "measure the print and estimate the warp only")
    significant = [n for n in shape if n in std and abs(shape[n]) > 3 * std[n]]
    moved = [k for k in ("fx", "fy", "cx", "cy") if abs(effect[k]) > max(res.std.get(k, 0.0), 1e-9)]
    if not significant or not moved:
        return out
    what = []
    if "pitch_ratio" in significant:
        what.append(f"y printed {100 * shape['pitch_ratio']:+.3f} % against x")
    warps = [f"{n} {1000 * shape[n]:+.2f} mm" for n in ("warp_x", "warp_y") if n in significant]
    if warps:
        what.append("sheet not flat (" + ", ".join(warps) + ")")
    moves = ", ".join(f"{k} {effect[k]:+.2f} px" for k in moved)
    return [*out, f"target shape matters: {'; '.join(what)}; against a flat, true-to-scale sheet it moves {moves}"]


MISFIT_RMS = 0.5  # px of edge RMS above which a pinhole model is checked against a fisheye one


PINHOLE_MAX_FIELD_DEG = 85.0  # rays this far from the axis are beyond what an x/z model can describe


PINHOLE_CHECK_RATIO = 0.7  # the field is estimated only when the edges reach r > 0.7 fx of the fit


class BeyondPinholeFieldError(CalibrationError):
    """The views see rays a pinhole model cannot describe: a fact about the lens and the views,
    estimated independently of the fit (no other start changes it)."""


def refuse_beyond_pinhole_field(usable: list[Detection], target: Target, lens: LensModel, size: ImageSize,
                                 fx: float, fisheye_field: Callable[[], float] | None = None) -> None:
    """A pinhole model (x = X/Z) cannot describe rays near or beyond 90 degrees, but fitted to a
    fisheye it may still reach a small RMS in one of several minima (which one was seen to change
    with the BLAS kernel, as was whether it drops the views at the rim as outliers). The field
    every usable view covers is estimated independently of the fit, with the generic fisheye lens
    r = f theta of :func:`equidistant_focal`; a field wider than PINHOLE_MAX_FIELD_DEG is refused.

    From straight rows (grids, checkerboards: their rays coplanar) that f is sound. From single
    rings it is not: it is the f that makes the edges most nearly conics in the virtual pinhole
    image, and a lens that is not equidistant (r = f tan(theta) (1 + k1 rho^2 + ...), k1 = -0.28)
    makes it low: 88-95 degrees were estimated for a lens whose image corners see 65. Such an
    estimate is replaced by ``fisheye_field()`` when given: the field (degrees) of the same edge
    points under the equidistant model *calibrated* on the views, theta = r (1 + k1 theta^2 + ...)
    / f with its f and coefficients fitted (it describes rays at and beyond 90 degrees, so a fisheye
    is still refused); NaN when that calibration fails (the generic estimate stands)."""
    w, h = size
    if not any(d.edges for d in usable):
        return  # corners only: the fold check (check_model_fits) covers them
    pts = np.concatenate([e.points for d in usable for e in d.edges])
    r = np.hypot(pts[:, 0] - w / 2, pts[:, 1] - h / 2)
    r_far = float(np.percentile(r, 99.9))
    if r_far < PINHOLE_CHECK_RATIO * fx:
        return  # the fitted pinhole itself puts every edge within ~35 degrees: nothing to check
    # a rough f is all this needs: a quarter of the edge points of at most 12 views
    sparse = [replace(d, edges=[replace(e, points=e.points[::4]) for e in d.edges])
              for d in usable[:: max(1, len(usable) // 12)]]
    field = float(np.degrees(r_far / equidistant_focal(sparse, target)))
    if field <= PINHOLE_MAX_FIELD_DEG:
        return
    if not has_straight_rows(sparse, target) and fisheye_field is not None:
        calibrated = fisheye_field()
        field = field if np.isnan(calibrated) else calibrated
        if field <= PINHOLE_MAX_FIELD_DEG:
            return
    raise BeyondPinholeFieldError(f"the views see rays up to about {field:.0f} degrees from the optical axis "
                                  f"(estimated with an equidistant fisheye lens); a {lens.name} model (x/z) cannot "
                                  "describe rays near or beyond 90 degrees: use --distortion equidistant (fisheye)")


# a fitted model that folds over under more than this share of the observed edge points is refused
# (a fit whose optimum lies in a flat valley, as a rational model on a fisheye, may fold more or less
# depending on the last bits: any such fold is a model that does not describe the lens)
FOLD_REFUSE_FRACTION = 0.0005


def check_model_fits(res: RefineResult, lens: LensModel, size: ImageSize) -> float:
    """A pinhole polynomial fitted to a lens wider than it can describe folds over: some observed
    edge points then have no ray (or not the one they came from). Refuse such a result and name
    the model to use, rather than publish a folded-over camera."""
    w, h = size
    cam = Camera(res.K, res.D, w, h, lens.name)
    ok, _ = consistent_rays(cam, np.concatenate([np.r_[v.points, v.corners] for v in res.views]), 0.05)
    bad = float(np.mean(~ok))
    if bad > FOLD_REFUSE_FRACTION:
        field = float(np.degrees(lens.max_angle(res.D)))
        advice = ("use --distortion equidistant (fisheye)" + (", or rational_polynomial for a wide-angle lens"
                                                              if lens.name == "plumb_bob" else "")
                  if not lens.wide else "check that the views show this target")
        raise CalibrationError(f"the fitted {lens.name} model folds over inside the observed field ({100 * bad:.1f} % "
                               "of the edge points and corners have no consistent ray; the model is monotonic "
                               f"only up to {field:.0f} degrees): this lens is wider than {lens.name} can describe; "
                               f"{advice}")
    return bad


def check_result(res: RefineResult, size: ImageSize, warnings: list[str]) -> None:
    w, h = size
    K = res.K
    if not (0 < K[0, 2] < w and 0 < K[1, 2] < h):
        raise CalibrationError(f"principal point ({K[0, 2]:.0f}, {K[1, 2]:.0f}) outside the image: the "
                               "views do not constrain the camera; add tilted views across the image")
    if res.rms > 1.0:
        warnings.append(f"edge RMS {res.rms:.2f} px is high: check focus, motion blur, target flatness")
    if not res.success:
        warnings.append(f"refinement stopped early: {res.message}")
