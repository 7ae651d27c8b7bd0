"""Zhang's method baseline: OpenCV ``calibrateCamera`` on checkerboard corners."""

from __future__ import annotations

import cv2
import numpy as np

from ..detect.detection import Detection
from ..geometry.iac import DegenerateViewsError
from ..targets import Target


def calibrate_zhang(dets: list[Detection], target: Target, distortion: str = "plumb_bob", zero_skew: bool = True
                    ) -> tuple[np.ndarray, np.ndarray, float, list[int], np.ndarray]:
    """K, D, RMS reprojection error (px), indices of the views used, per-parameter std
    (fx, fy, cx, cy, k1, k2, p1, p2, k3)."""
    board = target.checkerboard
    if board is None:
        raise ValueError(f"target {target.name!r} has no checkerboard: zhang needs one")
    obj = np.concatenate([board.corner_points(), np.zeros((len(board.corner_points()), 1))], 1).astype(np.float32)
    used = [k for k, d in enumerate(dets) if d.corners is not None]
    if len(used) < 3:
        raise DegenerateViewsError(f"zhang: checkerboard found in {len(used)} view(s); need at least 3")
    w, h = dets[0].width, dets[0].height
    flags = 0
    if distortion == "plumb_bob_k3_fixed":
        flags |= cv2.CALIB_FIX_K3
    elif distortion == "radial":
        flags |= cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    elif distortion == "none":
        flags |= cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    imgpts = [dets[k].corners.astype(np.float32).reshape(-1, 1, 2) for k in used]  # type: ignore[union-attr]
    if distortion == "equidistant":
        return _fisheye(obj, imgpts, used, w, h)
    if distortion == "rational_polynomial":
        flags |= cv2.CALIB_RATIONAL_MODEL
    out = cv2.calibrateCameraExtended([obj] * len(used), imgpts, (w, h), None, None,  # type: ignore[call-overload]
                                      flags=flags)
    rms, K, D = out[0], out[1], out[2]
    n = 8 if distortion == "rational_polynomial" else 5
    std = np.asarray(out[5]).ravel()[:4 + n]
    return K, np.asarray(D).ravel()[:n], float(rms), used, std


def _fisheye(obj: np.ndarray, imgpts: list[np.ndarray], used: list[int], w: int, h: int
             ) -> tuple[np.ndarray, np.ndarray, float, list[int], np.ndarray]:
    """OpenCV's fisheye calibration (it needs an intrinsic guess to converge; no standard
    deviations: reported as NaN). Rays beyond about 87 degrees make it fail: say so."""
    K0 = np.array([[w / 3.0, 0, w / 2.0], [0, w / 3.0, h / 2.0], [0, 0, 1.0]])
    # OpenCV 5 names the fisheye flags in the cv2 namespace
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-10)
    try:
        rms, K, D, _, _ = cv2.fisheye.calibrate([obj.reshape(-1, 1, 3).astype(np.float64)] * len(imgpts),
                                                [p.astype(np.float64) for p in imgpts], (w, h), K0, np.zeros(4),
                                                flags=flags, criteria=crit)
    except cv2.error as e:
        raise DegenerateViewsError(f"OpenCV's fisheye calibration failed ({str(e).strip().splitlines()[-1]}); "
                                   "corners near or beyond 90 degrees break it: use a circle method") from None
    return K, np.asarray(D).ravel()[:4], float(rms), used, np.full(8, np.nan)
