"""Plane-to-image homography: normalised DLT (Hartley & Zisserman, alg. 4.2), then
Levenberg-Marquardt on the transfer error in the image (as OpenCV's findHomography), float64."""

from __future__ import annotations

import numpy as np


def _normalizer(p: np.ndarray) -> np.ndarray:
    m = p.mean(0)
    s = np.sqrt(2) / max(float(np.mean(np.linalg.norm(p - m, axis=1))), 1e-300)
    return np.array([[s, 0, -s * m[0]], [0, s, -s * m[1]], [0, 0, 1.0]])


def fit_homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """H with dst ~ H src for (N, 2) point sets, N >= 4, in full double precision."""
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    if len(src) < 4 or src.shape != dst.shape:
        raise ValueError(f"need at least 4 point pairs of equal shape, got {src.shape} and {dst.shape}")
    Ts, Td = _normalizer(src), _normalizer(dst)
    s = np.c_[src, np.ones(len(src))] @ Ts.T
    d = np.c_[dst, np.ones(len(dst))] @ Td.T
    z = np.zeros((len(s), 3))
    A = np.concatenate([np.hstack([s, z, -d[:, :1] * s]), np.hstack([z, s, -d[:, 1:2] * s])])
    Hn = np.linalg.svd(A)[2][-1].reshape(3, 3)
    H = np.linalg.solve(Td, Hn @ Ts)
    H = H / H[2, 2]
    if len(src) > 4:
        from scipy.optimize import least_squares

        X = np.c_[src, np.ones(len(src))]

        def transfer(h: np.ndarray) -> np.ndarray:
            p = X @ np.append(h, 1.0).reshape(3, 3).T
            return (p[:, :2] / p[:, 2:3] - dst).ravel()

        H = np.append(least_squares(transfer, H.ravel()[:8], method="lm", xtol=1e-12, ftol=1e-12).x, 1.0)
        H = H.reshape(3, 3)
    return H
