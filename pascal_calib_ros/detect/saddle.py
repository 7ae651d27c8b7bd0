"""Checkerboard corners as centres of point symmetry: refined, and checked, against the image.

Locally, two straight edges crossing at a corner ``c`` (an X-junction, whatever the angle between
them) make an image that is point-symmetric about ``c``: ``I(c + d) = I(c - d)`` for every offset
``d`` inside the four squares around it. This stays exact after any blur that is itself symmetric
(optics, defocus, the sensor's pixel), any monotonic grey-level response (gamma) and any tilt of
the board; lens distortion bends the edges and departs from it only to second order. A corner is
therefore refined as the point about which the image is most nearly point-symmetric over a disc
of radius ``rho``, by Gauss-Newton on the residuals ``r_d(c) = I(c + d) - I(c - d)`` (Jacobian
``grad I(c + d) - grad I(c - d)``), the disc kept inside the corner's own squares; the same
residuals, left over at the solution, say whether the point is a corner at all.

Point symmetry is what tells an X-junction from an edge, a blob or a flat patch in the ChESS
corner detector (Bennett & Lasenby, "ChESS - Quick and robust detection of chess-board features",
CVIU 118:197-210, 2014: its "difference response" sums |I(c + d) - I(c - d)| over a ring); here
its least-squares form over a disc locates the corner to a fraction of a pixel. Against
``cv2.cornerSubPix`` (every gradient in the window orthogonal to the line from the corner,
Foerstner) with the same windows, measured by ``tools/corner_accuracy.py``: half the error on
renders, unmoved by blur as wide as small squares (cornerSubPix wandered 1-3 px), and not pulled
towards the board's edge where the outer squares are narrower than the window expected (1.5-3 px
for cornerSubPix on OpenCV's sample photos).

The image is sampled bilinearly in square tiles cut around the corners (never the whole frame,
which at 5 MP costs more than everything else).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

RINGS, ANGLES = 6, 16  # samples of the disc: rings, and angles over half a turn (a pair covers both)
ITERATIONS = 10
TOLERANCE = 0.005  # px: a step smaller than this ends the iteration (Gauss-Newton: the next would be far smaller)


def _unit_pairs() -> tuple[np.ndarray, np.ndarray]:
    """(M, 2) offsets over the upper half of the unit disc (rings at the middle of equal annuli)
    and (M,) weights proportional to the area each stands for."""
    fr = (np.arange(RINGS) + 0.5) / RINGS
    ang = np.arange(ANGLES) * np.pi / ANGLES
    d = np.stack([np.outer(fr, np.cos(ang)).ravel(), np.outer(fr, np.sin(ang)).ravel()], -1)
    return d, np.repeat(fr, ANGLES) / (fr.sum() * ANGLES)


_UNIT, _WEIGHT = _unit_pairs()


class _Tiles:
    """Square tiles of the frame around points (float32 grey and its central-difference
    gradient), sampled bilinearly at frame coordinates; samples beyond a tile are clamped to it."""

    def __init__(self, gray8: np.ndarray, centres: np.ndarray, half: int):
        h, w = gray8.shape[:2]
        self.size = s = 2 * half + 1
        self.origin = np.round(centres).astype(int) - half  # (N, 2) frame pixel of each tile's (0, 0)
        tiles = np.empty((len(centres), s, s), np.float32)
        inside = np.all((self.origin >= 0) & (self.origin + s <= (w, h)), axis=1)
        for n, (x0, y0) in enumerate(self.origin.tolist()):
            if inside[n]:
                tiles[n] = gray8[y0:y0 + s, x0:x0 + s]
            else:  # beyond the frame: its border pixels repeated
                ys, xs = np.clip(np.arange(y0, y0 + s), 0, h - 1), np.clip(np.arange(x0, x0 + s), 0, w - 1)
                tiles[n] = gray8[np.ix_(ys, xs)]
        mosaic = tiles.reshape(-1, s)
        gx = cv2.Sobel(mosaic, cv2.CV_32F, 1, 0, ksize=1, scale=0.5)
        gy = cv2.Sobel(mosaic, cv2.CV_32F, 0, 1, ksize=1, scale=0.5)
        self.mosaic = cv2.merge([mosaic, gx, gy])

    def sample(self, pts: np.ndarray, tile: np.ndarray) -> np.ndarray:
        """(K, M, 3): grey level, d/dx, d/dy at frame points ``pts`` (K, M, 2), row k in tile ``tile[k]``."""
        s = self.size
        local = pts - self.origin[tile][:, None, :]
        x = np.clip(local[..., 0], 1, s - 2).astype(np.float32)
        y = (np.clip(local[..., 1], 1, s - 2) + (tile * s)[:, None]).astype(np.float32)
        return cv2.remap(self.mosaic, x, y, cv2.INTER_LINEAR)


@dataclass(frozen=True)
class SaddleFit:
    """Corners refined by point symmetry, and how well the image agrees with a corner there."""

    points: np.ndarray  # (N, 2) px
    rms: np.ndarray  # (N,) grey levels: RMS of I(c + d) - I(c - d) over the disc at the solution
    spread: np.ndarray  # (N,) grey levels: standard deviation of I over the disc (a flat patch is symmetric too)
    moved: np.ndarray  # (N,) px from the starting point

    @property
    def symmetry(self) -> np.ndarray:
        """(N,) 1 - rms / (sqrt 2 spread): 1 point-symmetric, 0 unrelated pairs, < 0 an edge."""
        return 1 - self.rms / np.maximum(np.sqrt(2) * self.spread, 1e-6)


def _residuals(tiles: _Tiles, c: np.ndarray, d: np.ndarray, tile: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals I(c + d) - I(c - d) (K, M) for offsets ``d`` (K, M, 2), their Jacobian in c
    (K, M, 2) and the grey levels sampled (K, 2 M)."""
    cc = c[:, None].astype(np.float32)
    v = tiles.sample(np.concatenate([cc + d, cc - d], 1), tile)
    m = d.shape[1]
    return v[:, :m, 0] - v[:, m:, 0], v[:, :m, 1:] - v[:, m:, 1:], v[..., 0]


def refine_saddles(gray8: np.ndarray, points: np.ndarray, radii: np.ndarray, max_move: float | None = None
                   ) -> SaddleFit:
    """Refine corners to the centre of point symmetry of the image over discs of ``radii``.

    Parameters
    ----------
    gray8 : (H, W) uint8 image.
    points : (N, 2) starting points, px (within a few px of the corners).
    radii : (N,) disc radius per corner, px (inside the corner's own squares).
    max_move : farthest a corner may move from its start, px (default: half its radius).

    Returns
    -------
    SaddleFit with the refined points, and the symmetry and spread of the image about them (as
    sampled before the last step, smaller than ``TOLERANCE``, or after ``ITERATIONS`` steps).
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    n = len(pts)
    rho = np.broadcast_to(np.asarray(radii, float), (n,)).copy()
    limit = 0.5 * rho if max_move is None else np.full(n, float(max_move))
    rms, spread = np.zeros(n), np.zeros(n)
    if not n:
        return SaddleFit(pts.copy(), rms, spread, rms.copy())
    tiles = _Tiles(gray8, pts, int(np.ceil(np.max(rho + limit))) + 2)
    d = (rho[:, None, None] * _UNIT[None]).astype(np.float32)
    c = pts.copy()
    idx = np.arange(n)
    for _ in range(ITERATIONS):
        r, J, v = _residuals(tiles, c[idx], d[idx], idx)
        rms[idx], spread[idx] = np.sqrt((r**2) @ _WEIGHT), np.std(v, axis=1)
        step, ok = _gauss_newton_step(r, J, _WEIGHT)
        size = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, 0.5 * rho[idx] / np.maximum(size, 1e-12))[:, None]
        off = c[idx] + step - pts[idx]
        far = np.linalg.norm(off, axis=1)
        c[idx] = pts[idx] + off * np.minimum(1.0, limit[idx] / np.maximum(far, 1e-12))[:, None]
        idx = idx[(size >= TOLERANCE) & ok]
        if not len(idx):
            break
    return SaddleFit(c, rms, spread, np.linalg.norm(c - pts, axis=1))


def _gauss_newton_step(r: np.ndarray, J: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 2) Gauss-Newton steps for residuals (K, M) with Jacobians (K, M, 2) and weights (M,),
    and (K,) whether the normal matrix was regular (else the step is 0)."""
    Jw = J.transpose(0, 2, 1) * weight  # (K, 2, M)
    A = Jw @ J
    g = (Jw @ r[..., None])[..., 0]
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] ** 2
    ok = det > 1e-9 * np.maximum(A[:, 0, 0] * A[:, 1, 1], 1e-30)
    step = np.zeros_like(g)
    step[ok] = -np.linalg.solve(A[ok], g[ok][..., None])[..., 0]
    return step, ok
