"""The true error of a guided study session's camera: its projection error over the whole image
against the rendered truth."""

from __future__ import annotations

import numpy as np

from ..analysis import CompareError, projection_difference
from ..geometry import Camera, model_for_coefficients


def true_errors(truth: Camera, K: np.ndarray, D: np.ndarray, model: str, step: int = 16
                ) -> tuple[float, float, float, float]:
    """(RMS, worst) of the estimate's projection error over the whole image (16 px grid): after
    the rotation between the two camera frames that fits best (mrcal's projection_diff at
    infinity, :func:`..analysis.compare.projection_difference`; a constant rotation is a mounting
    the extrinsics absorb, as the views' poses absorb it in the calibration), then raw (the
    displacement between where the true camera and the estimate image each grid pixel's ray)."""
    est = Camera(K, D, truth.width, truth.height, model_for_coefficients(D, model).name)
    try:
        mag = projection_difference(truth, est, None, None, float(step)).magnitude
        rot = (float(np.sqrt(np.mean(mag**2))), float(np.max(mag)))
    except CompareError:
        rot = (float("nan"), float("nan"))
    us, vs = np.meshgrid(np.arange(0, truth.width, step) + 0.5, np.arange(0, truth.height, step) + 0.5)
    uv = np.stack([us.ravel(), vs.ravel()], 1)
    rays = truth.unproject(uv)
    ok = np.all(np.isfinite(rays), 1)
    if not est.lens.wide:
        ok &= rays[:, 2] > 1e-6
    d = np.linalg.norm(est.project(rays[ok]) - uv[ok], axis=1)
    d = d[np.isfinite(d)]
    raw = (float(np.sqrt(np.mean(d * d))), float(np.max(d))) if len(d) else (float("nan"), float("nan"))
    return (*rot, *raw)


__all__ = ["true_errors"]
