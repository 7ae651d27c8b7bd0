"""Zhang's method baseline: OpenCV ``calibrateCamera`` on checkerboard corners."""

from __future__ import annotations

import cv2
import numpy as np

from ..detect.rings import Detection
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
    out = cv2.calibrateCameraExtended([obj] * len(used), imgpts, (w, h), None, None,  # type: ignore[call-overload]
                                      flags=flags)
    rms, K, D = out[0], out[1], out[2]
    std = np.asarray(out[5]).ravel()[:9]
    return K, np.asarray(D).ravel()[:5], float(rms), used, std
