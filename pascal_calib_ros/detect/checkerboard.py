"""Checkerboard inner corners in the target's order: found on a reduced copy, refined at full
resolution.

1. The board is searched on a copy of the frame halved (``cv2.pyrDown``) until it has at most
   ``COARSE_PIXELS`` pixels, with OpenCV's quad detector (``findChessboardCorners``, adaptive
   threshold, fast check); failing that on the next finer copy if it is small enough, then with
   ``findChessboardCornersSB`` (without its slow exhaustive and accuracy passes) on the reduced
   copy. A full 5 MP frame is never searched: that took seconds.
2. Every corner is refined at full resolution with ``cv2.cornerSubPix`` (the gradient of the image
   is orthogonal to the line from the corner to any point of its two edges). The search window is
   chosen per corner from the board as seen (:func:`corner_windows`): a fraction of the distance
   from the corner to the nearest side of an adjacent square that does not pass through it, so
   that the window holds only the corner's own two edges, whatever the size, tilt and distortion
   of the squares. ``camera_calibration`` (ROS image_pipeline) detects on a reduced copy and
   refines at full resolution the same way, with one window for all corners. The windows are
   chosen again from the refined corners and the refinement repeated once. A refined corner about
   which the image is not point-symmetric (:func:`corner_symmetry`: it sits on an edge, its coarse
   estimate was too far off, as at the edge of a strongly distorted board) is searched again from
   where its row and column predict it; if it still is not on a crossing, the board is not taken.
3. Order. OpenCV returns the grid from either end (180 degrees), and the handedness of its order
   is not promised: a mirrored order is flipped first (a board seen from its printed side keeps
   the handedness of the sheet). The 180 degree ambiguity is resolved by the ring when the view
   has one (the ring's centre mapped with the homography of each candidate order must land on the
   detected centre), else by the colour of the squares when the board's two halves differ
   (an odd total number of squares along x and y, as every shipped board has).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry.circular import CircularPointError, centre_image_from_ring
from ..targets import Checkerboard, Target
from .detection import Detection

COARSE_PIXELS = 600_000  # the board is searched on a copy halved until it has at most this many pixels
FINE_PIXELS = 1_400_000  # ... failing that, on the next finer copy if it has at most this many
WINDOW_FRACTION = 0.4  # cornerSubPix half-window: this fraction of the corner's clearance (px) ...
MIN_HALF_WINDOW, MAX_HALF_WINDOW = 2, 25  # ... within these bounds
MIN_SYMMETRY = 0.5  # a refined corner less point-symmetric than this is not on the crossing of its edges
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)


def find_checkerboard(gray8: np.ndarray, target: Target, det: Detection | None = None) -> np.ndarray | None:
    """(N, 2) inner corners in ``Checkerboard.corner_points`` order, or None if not found."""
    board = target.checkerboard
    if board is None:
        return None
    nx, ny = board.inner_corners
    coarse = coarse_corners(gray8, (nx, ny))
    if coarse is None:
        return None
    grid = _repaired(gray8, refine_corners(gray8, _right_handed(coarse.reshape(ny, nx, 2))))
    if grid is None:
        return None
    corners = grid.reshape(-1, 2)
    by_ring = _order_by_ring(corners, target, det)
    if by_ring is not None:
        return by_ring
    return _order_by_colour(gray8, corners, board)


def _pyramid(gray8: np.ndarray, max_pixels: int) -> list[tuple[np.ndarray, int]]:
    """The frame and its halved copies down to the first with at most ``max_pixels``, with their
    scale factors."""
    levels = [(gray8, 1)]
    while levels[-1][0].size > max_pixels and min(levels[-1][0].shape) >= 64:
        img, s = levels[-1]
        levels.append((cv2.pyrDown(img), 2 * s))
    return levels


def coarse_corners(gray8: np.ndarray, size: tuple[int, int]) -> np.ndarray | None:
    """(N, 2) inner corners in full-resolution pixels (OpenCV's order) as found on a reduced copy
    of the frame, accurate to about a pixel of that copy, or None."""
    levels = _pyramid(gray8, COARSE_PIXELS)
    tries = [levels[-1]]
    if len(levels) > 1 and levels[-2][0].size <= FINE_PIXELS:
        tries.append(levels[-2])
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    for img, s in tries:
        found, c = cv2.findChessboardCorners(img, size, flags=flags)
        if found and c is not None:
            return _to_full(c, s)
    img, s = levels[-1]
    found, c = cv2.findChessboardCornersSB(img, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    if found and c is not None:
        return _to_full(c, s)
    return None


def _to_full(c: np.ndarray, scale: int) -> np.ndarray:
    # cv2.pyrDown centres its kernel on pixel 2k: pixel k of a copy halved n times is at s k
    return np.asarray(c, float).reshape(-1, 2) * scale


def _right_handed(grid: np.ndarray) -> np.ndarray:
    """The (ny, nx, 2) grid with its rows reversed if its order is mirrored against the sheet's
    (x to the right, y down, seen from the printed side: positive cross products in pixels)."""
    u = grid[:-1, 1:] - grid[:-1, :-1]
    v = grid[1:, :-1] - grid[:-1, :-1]
    cross = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return grid[::-1].copy() if np.sum(np.sign(cross)) < 0 else grid


def _extended(grid: np.ndarray) -> np.ndarray:
    """The grid with one more row and column of corners on every side, extrapolated quadratically
    (the outer squares, foreshortened and distorted like their neighbours)."""
    def ext(a: np.ndarray, b: np.ndarray, c: np.ndarray | None) -> np.ndarray:
        return 2 * a - b if c is None else 3 * a - 3 * b + c

    def third(g: np.ndarray, k: int, axis: int) -> np.ndarray | None:
        return None if g.shape[axis] < 3 else np.take(g, [k], axis=axis)

    g = grid
    g = np.concatenate([ext(g[:, :1], g[:, 1:2], third(g, 2, 1)), g,
                        ext(g[:, -1:], g[:, -2:-1], third(g, -3, 1))], axis=1)
    g = np.concatenate([ext(g[:1], g[1:2], third(g, 2, 0)), g, ext(g[-1:], g[-2:-1], third(g, -3, 0))], axis=0)
    return g


def corner_clearance(grid: np.ndarray) -> np.ndarray:
    """(ny, nx): for every corner, the distance (px) to the nearest side of its four adjacent
    squares that does not pass through it (each square taken as the parallelogram of the corner's
    two edges to its neighbours; squares outside the inner grid extrapolated)."""
    g = _extended(grid)
    ny, nx = grid.shape[:2]
    p = g[1:-1, 1:-1]
    out = np.full((ny, nx), np.inf)
    for sy in (-1, 1):
        for sx in (-1, 1):
            u = g[1:-1, 1 + sx:g.shape[1] - 1 + sx] - p
            v = g[1 + sy:g.shape[0] - 1 + sy, 1:-1] - p
            area = np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
            lu = np.maximum(np.linalg.norm(u, axis=-1), 1e-9)
            lv = np.maximum(np.linalg.norm(v, axis=-1), 1e-9)
            out = np.minimum(out, np.minimum(area / lu, area / lv))
    return out


def corner_windows(grid: np.ndarray) -> np.ndarray:
    """(ny, nx) ``cornerSubPix`` half-windows (px): ``WINDOW_FRACTION`` of each corner's clearance."""
    r = np.round(WINDOW_FRACTION * corner_clearance(grid))
    return np.clip(r, MIN_HALF_WINDOW, MAX_HALF_WINDOW).astype(int)


def refine_corners(gray8: np.ndarray, grid: np.ndarray, passes: int = 2) -> np.ndarray:
    """(ny, nx, 2) corners refined by ``cv2.cornerSubPix`` on the full-resolution frame, each with
    its own window (:func:`corner_windows`). The windows of the second pass come from the corners
    of the first: the coarse corners (a pixel or two off) can make the extrapolated outer squares
    look smaller than they are."""
    for _ in range(passes):
        win = corner_windows(grid).ravel()
        pts = grid.reshape(-1, 2).astype(np.float32)
        for r in np.unique(win):
            idx = np.flatnonzero(win == r)
            p = pts[idx].reshape(-1, 1, 2).copy()
            cv2.cornerSubPix(gray8, p, (int(r), int(r)), (-1, -1), _SUBPIX_CRITERIA)
            pts[idx] = p.reshape(-1, 2)
        grid = pts.astype(float).reshape(grid.shape)
    return grid


def corner_symmetry(gray8: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(ny, nx) point symmetry of the image about each corner, 1 - mean |I(c + d) - I(c - d)| /
    contrast on a circle of 0.75 half-windows: near 1 on the crossing of two edges (0.96 or more
    in 99.9 % of rendered corners, 0.64 at least), near 0 on a single edge or beside the corner."""
    pts = grid.reshape(-1, 2)
    radius = np.maximum(2.0, 0.75 * corner_windows(grid).ravel())
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    mx = (pts[:, :1] + radius[:, None] * np.cos(ang)).astype(np.float32)
    my = (pts[:, 1:] + radius[:, None] * np.sin(ang)).astype(np.float32)
    v = cv2.remap(gray8, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(float)
    contrast = np.maximum(v.max(1) - v.min(1), 1.0)
    return (1 - np.mean(np.abs(v[:, :8] - v[:, 8:]), 1) / contrast).reshape(grid.shape[:2])


def grid_predictions(grid: np.ndarray) -> np.ndarray:
    """(ny, nx, 2): every corner predicted from its row and its column (cubic interpolation between
    two neighbours on each side, cubic extrapolation from three on one side; NaN corners are not
    used), the median of the predictions; NaN where there is none."""
    preds = []
    for along_x in (True, False):
        g = grid if along_x else grid.transpose(1, 0, 2)
        P = np.full((3, *g.shape), np.nan)
        if g.shape[1] >= 5:
            P[0][:, 2:-2] = (-g[:, :-4] + 4 * g[:, 1:-3] + 4 * g[:, 3:-1] - g[:, 4:]) / 6
        if g.shape[1] >= 4:
            P[1][:, 3:] = 3 * g[:, 2:-1] - 3 * g[:, 1:-2] + g[:, :-3]
            P[2][:, :-3] = 3 * g[:, 1:-2] - 3 * g[:, 2:-1] + g[:, 3:]
        else:
            P[0][:, 1:-1] = (g[:, :-2] + g[:, 2:]) / 2
            P[1][:, 2:] = 2 * g[:, 1:-1] - g[:, :-2]
            P[2][:, :-2] = 2 * g[:, 1:-1] - g[:, 2:]
        preds.append(P if along_x else P.transpose(0, 2, 1, 3))
    stack = np.concatenate(preds)
    out = np.full(grid.shape, np.nan)
    have = np.isfinite(stack[..., 0]).any(0)
    out[have] = np.nanmedian(stack[:, have], axis=0)
    return out


def _repaired(gray8: np.ndarray, grid: np.ndarray) -> np.ndarray | None:
    """The refined grid with every corner that is not on a crossing of edges (a coarse corner too
    far off for its window, seen at the board's edge under strong distortion) searched again from
    the position its row and column predict; None if one stays off."""
    bad = corner_symmetry(gray8, grid) < MIN_SYMMETRY
    if not bad.any():
        return grid
    known = grid.copy()
    known[bad] = np.nan
    pred = grid_predictions(known)
    if not np.isfinite(pred[bad]).all():
        return None
    seeded = grid.copy()
    seeded[bad] = pred[bad]
    win = corner_windows(seeded)
    for j, i in zip(*np.nonzero(bad), strict=True):
        p = seeded[j, i].astype(np.float32).reshape(1, 1, 2)
        cv2.cornerSubPix(gray8, p, (int(win[j, i]), int(win[j, i])), (-1, -1), _SUBPIX_CRITERIA)
        seeded[j, i] = p.ravel()
    return seeded if (corner_symmetry(gray8, seeded)[bad] >= MIN_SYMMETRY).all() else None


def _order_by_ring(corners: np.ndarray, target: Target, det: Detection | None) -> np.ndarray | None:
    """The candidate order (as found, or reversed) whose homography maps the ring's centre onto the
    detected one; None when the view has no measured ring."""
    board = target.checkerboard
    if board is None or det is None or not target.rings or det.edge(0) is None or det.edge(1) is None:
        return None
    e0, e1 = det.edge(0), det.edge(1)
    assert e0 is not None and e1 is not None
    try:
        c = centre_image_from_ring(e0.conic, e1.conic)
    except CircularPointError:
        return None
    obj = board.corner_points()
    best: tuple[float, np.ndarray] | None = None
    for cand in (corners, corners[::-1].copy()):
        H, _ = cv2.findHomography(obj, cand)
        if H is None:
            continue
        p = H @ np.array([target.rings[0].center[0], target.rings[0].center[1], 1.0])
        d = float(np.hypot(*(p[:2] / p[2] - c[:2])))
        if best is None or d < best[0]:
            best = (d, cand)
    return None if best is None else best[1]


def _order_by_colour(gray8: np.ndarray, corners: np.ndarray, board: Checkerboard) -> np.ndarray:
    """Corners as found or reversed, whichever puts the dark squares where the board has them.
    Boards whose order reversed has the same colours (an even total of squares) stay as found."""
    sx, sy = board.squares
    if (sx + sy) % 2 == 0:
        return corners
    nx, ny = board.inner_corners
    g = corners.reshape(ny, nx, 2)
    centres = (g[:-1, :-1] + g[:-1, 1:] + g[1:, :-1] + g[1:, 1:]) / 4  # square (i + 1, j + 1) at [j, i]
    h, w = gray8.shape[:2]
    x = np.clip(np.round(centres[..., 0]).astype(int), 0, w - 1)
    y = np.clip(np.round(centres[..., 1]).astype(int), 0, h - 1)
    value = gray8[y, x].astype(float)
    jj, ii = np.mgrid[0:ny - 1, 0:nx - 1]
    dark = ((ii + jj) % 2 == 0) == (board.first_square == "black")  # squares (i + 1, j + 1)
    if value[dark].mean() > value[~dark].mean():
        return corners[::-1].copy()
    return corners
