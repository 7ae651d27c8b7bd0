"""Zhang's method: OpenCV ``calibrateCamera`` on checkerboard corners — the closed-form start
(and the refinement OpenCV does itself) of the checkerboard path, and the baseline with
``--no-refine`` (Zhang, "A flexible new technique for camera calibration", PAMI 22(11), 2000)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ...detect import Detection
from ...geometry import DegenerateViewsError, ImageSize
from ...targets import Target
from .initial import PlanePose

MIN_CORNERS = 6  # a view needs this many measured corners (OpenCV's homography needs 4)


@dataclass(frozen=True)
class ZhangResult:
    """OpenCV's calibration of the checkerboard views: K, D (the model's coefficients), RMS
    reprojection error (px), the views used (indices into the session), OpenCV's i.i.d. standard
    deviations (fx, fy, cx, cy, then D; NaN where it gives none) and each used view's pose of the
    target's local frame (origin ``origin`` on the sheet)."""

    K: np.ndarray
    D: np.ndarray
    rms: float
    used: list[int]
    std: np.ndarray
    poses: list[PlanePose]


def calibrate_zhang(dets: list[Detection], target: Target, distortion: str = "plumb_bob",
                    origin: tuple[float, float] = (0.0, 0.0)) -> ZhangResult:
    """OpenCV's calibration on the measured corners of every view (corners the detector rejected
    are NaN and left out); the poses are returned in the local frame x_local = x_target - origin."""
    board = target.board
    if board is None:
        raise ValueError(f"target {target.name!r} has no checkerboard: zhang needs one")
    grid = board.corner_points()
    used, obj, img = [], [], []
    for k, d in enumerate(dets):
        if d.corners is None or not d.ok:
            continue
        ok = np.all(np.isfinite(d.corners), 1)
        if ok.sum() < MIN_CORNERS:
            continue
        used.append(k)
        obj.append(np.c_[grid[ok], np.zeros(ok.sum())].astype(np.float32))
        img.append(d.corners[ok].astype(np.float32).reshape(-1, 1, 2))
    if len(used) < 3:
        raise DegenerateViewsError(f"zhang: checkerboard found in {len(used)} view(s); need at least 3")
    w, h = dets[used[0]].width, dets[used[0]].height
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # OpenCV's threads make its last bits (~1e-13) differ from run to run
    try:
        if distortion == "equidistant":
            K, D, rms, rvecs, tvecs, std = _fisheye(obj, img, ImageSize(w, h))
        else:
            K, D, rms, rvecs, tvecs, std = _pinhole(obj, img, ImageSize(w, h), distortion)
    finally:
        cv2.setNumThreads(threads)
    o = np.array([origin[0], origin[1], 0.0])
    poses = []
    for rv, tv in zip(rvecs, tvecs, strict=True):
        R = cv2.Rodrigues(np.asarray(rv, float).reshape(3, 1))[0]
        poses.append(PlanePose(R, np.asarray(tv, float).ravel() + R @ o))
    return ZhangResult(K, D, rms, used, std, poses)


_FLAGS = {"plumb_bob": 0, "plumb_bob_k3_fixed": cv2.CALIB_FIX_K3,
          "radial": cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
          "none": cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
          "rational_polynomial": cv2.CALIB_RATIONAL_MODEL}


def _pinhole(obj: list[np.ndarray], img: list[np.ndarray], size: ImageSize, distortion: str
             ) -> tuple[np.ndarray, np.ndarray, float, list[np.ndarray], list[np.ndarray], np.ndarray]:
    w, h = size
    out = cv2.calibrateCameraExtended(obj, img, (w, h), None, None,  # type: ignore[call-overload]
                                      flags=_FLAGS[distortion])
    rms, K, D, rvecs, tvecs = out[0], out[1], out[2], out[3], out[4]
    n = 8 if distortion == "rational_polynomial" else 5
    std = np.asarray(out[5]).ravel()[:4 + n]
    return K, np.asarray(D).ravel()[:n], float(rms), list(rvecs), list(tvecs), std


def _fisheye(obj: list[np.ndarray], img: list[np.ndarray], size: ImageSize
             ) -> tuple[np.ndarray, np.ndarray, float, list[np.ndarray], list[np.ndarray], np.ndarray]:
    """OpenCV's fisheye calibration (it needs an intrinsic guess to converge; no standard
    deviations: reported as NaN). Rays beyond about 87 degrees make it fail: say so."""
    w, h = size
    K0 = np.array([[w / 3.0, 0, w / 2.0], [0, w / 3.0, h / 2.0], [0, 0, 1.0]])
    # OpenCV 5 names the fisheye flags in the cv2 namespace
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-10)
    try:
        rms, K, D, rvecs, tvecs = cv2.fisheye.calibrate([o.reshape(-1, 1, 3).astype(np.float64) for o in obj],
                                                        [p.astype(np.float64) for p in img], (w, h), K0, np.zeros(4),
                                                        flags=flags, criteria=crit)
    except cv2.error as e:
        raise DegenerateViewsError(f"OpenCV's fisheye calibration failed ({str(e).strip().splitlines()[-1]}); "
                                   "corners near or beyond 90 degrees break it: use a circle method") from None
    return K, np.asarray(D).ravel()[:4], float(rms), list(rvecs), list(tvecs), np.full(8, np.nan)
