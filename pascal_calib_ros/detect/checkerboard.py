"""Checkerboard inner corners in the target's order: found on a reduced copy, refined at full
resolution.

1. The board is searched on a copy of the frame halved (``cv2.pyrDown``) until it has at most
   ``COARSE_PIXELS`` pixels, with OpenCV's quad detector (``findChessboardCorners``, adaptive
   threshold, fast check); failing that on the next finer copy if it is small enough, then with
   ``findChessboardCornersSB`` (without its slow exhaustive and accuracy passes) on the reduced
   copy. A full 5 MP frame is never searched: that took seconds.
2. Every corner is refined at full resolution as the centre of point symmetry of the image
   (:mod:`.saddle`) over a disc chosen per corner from the board as seen (:func:`corner_radii`):
   a fraction of the distance from the corner to the nearest side of an adjacent square that does
   not pass through it, so that the disc holds only the corner's own two edges, whatever the size,
   tilt and distortion of the squares. ``camera_calibration`` (ROS image_pipeline) detects on a
   reduced copy and refines at full resolution the same way, with ``cv2.cornerSubPix`` and one
   window for all corners. Point symmetry replaced ``cornerSubPix`` (with per-corner windows):
   twice as accurate on renders, unmoved by blur as wide as small squares, and on a board trimmed
   at its squares (OpenCV's sample photos) ``cornerSubPix`` was pulled 1.5-3 px towards the
   board's edge where the outer squares are narrower than the window expected
   (``tools/corner_accuracy.py``, NOTES_corners.md).
3. Check (:func:`saddle_grid`). A refined corner about which the image is not point-symmetric
   like the board's other corners (an occluder, a smudge or a glare over it, an edge, a flat
   patch) is searched again from where its row and column predict it (its coarse estimate too
   far off, as at the edge of a strongly distorted board), on the border of the grid over half
   the disc (a trimmed outer square); one that still is not is returned as NaN, and the board is
   refused when fewer than half of its corners remain.
4. Order. OpenCV returns the grid from either end (180 degrees), and the handedness of its order
   is not promised: a mirrored order is flipped first (a board seen from its printed side keeps
   the handedness of the sheet). The 180 degree ambiguity is resolved by the ring when the view
   has one (the ring's centre mapped with the homography of each candidate order must land on the
   detected centre), else by the colour of the squares when the board's two halves differ
   (an odd total number of squares along x and y, as every shipped board has).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry import CircularPointError, centre_image_from_ring
from ..targets import Checkerboard, Target
from .detection import Detection, DetectionRefusal
from .saddle import SaddleFit, refine_saddles

COARSE_PIXELS = 600_000  # the board is searched on a copy halved until it has at most this many pixels
FINE_PIXELS = 1_400_000  # ... failing that, on the next finer copy if it has at most this many
WINDOW_FRACTION = 0.4  # refine_corners: cornerSubPix half-window, this fraction of the clearance (px) ...
MIN_HALF_WINDOW, MAX_HALF_WINDOW = 2, 25  # ... within these bounds
RADIUS_FRACTION = 0.4  # a corner is refined over a disc of this fraction of its clearance (px) ...
MIN_RADIUS, MAX_RADIUS = 2.0, 12.0  # ... within these bounds
# the check of a refined corner (measured: tools/corner_accuracy.py, NOTES_corners.md)
MAX_ASYMMETRY = 3.0  # not on a saddle: residual asymmetry above this multiple of the board's lower quartile ...
MIN_SYMMETRY = 0.5  # ... or less point-symmetric than this (an edge: < 0) ...
MIN_SPREAD = 0.3  # ... or grey-level spread below this fraction of the board's median (a flat patch)
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)


def find_checkerboard(gray8: np.ndarray, target: Target, det: Detection | None = None) -> np.ndarray | None:
    """(N, 2) inner corners in ``Checkerboard.corner_points`` order, a NaN row for every corner the
    image does not show as a saddle (``det.note`` says how many); None if the board is not found
    or fewer than half of its corners are saddles (then ``det.reason``, or ``det.note`` when the
    target has a ring to go on with, says why)."""
    board = target.checkerboard
    if board is None:
        return None
    nx, ny = board.inner_corners
    coarse = coarse_corners(gray8, (nx, ny))
    if coarse is None:
        return None
    grid, ok = saddle_grid(gray8, right_handed(coarse.reshape(ny, nx, 2)))
    n, bad = ok.size, int(ok.size - ok.sum())
    if 2 * bad > n:
        _tell(det, f"checkerboard not used: {bad} of {n} corners are not on a saddle (occluded, "
                   "smudged or glared?)", refuse=not target.rings)
        return None
    if bad:
        _tell(det, f"{bad} of {n} corners rejected: not on a saddle")
    grid[~ok] = np.nan
    corners = grid.reshape(-1, 2)
    by_ring = _order_by_ring(corners, target, det)
    if by_ring is not None:
        return by_ring
    return _order_by_colour(gray8, corners, board)


def _tell(det: Detection | None, text: str, refuse: bool = False) -> None:
    """Say ``text`` on the detection: as its reason (the view refused: too few of the board's
    corners are saddles) or appended to its note."""
    if det is None:
        return
    if refuse:
        det.refuse(DetectionRefusal.TOO_FEW_FEATURES, text)
    else:
        det.note = f"{det.note}; {text}" if det.note else text


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


def right_handed(grid: np.ndarray) -> np.ndarray:
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
    look smaller than they are. Not used by :func:`find_checkerboard` (point symmetry replaced it);
    the OpenCV baseline of ``studies/study.py`` (SB corners + cornerSubPix) refines with it."""
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


def corner_radii(grid: np.ndarray) -> np.ndarray:
    """(ny, nx) radii (px) of the discs over which each corner is refined and checked:
    ``RADIUS_FRACTION`` of its clearance, within ``MIN_RADIUS`` .. ``MAX_RADIUS``."""
    return np.clip(RADIUS_FRACTION * corner_clearance(grid), MIN_RADIUS, MAX_RADIUS)


def _on_saddle(fit: SaddleFit, board: SaddleFit) -> np.ndarray:
    """Which refined corners the image shows as saddles: about as point-symmetric as the board's
    clean corners (not spoiled by a blob, a smudge or a glare; the lower quartile of the board's
    asymmetry stands for them, right while a quarter of the corners is clean), point-symmetric at
    all (not an edge), and with about the board's contrast (not a flat patch)."""
    return ((fit.rms <= MAX_ASYMMETRY * np.percentile(board.rms, 25)) & (fit.symmetry >= MIN_SYMMETRY)
            & (fit.spread >= MIN_SPREAD * np.median(board.spread)))


def saddle_grid(gray8: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (ny, nx, 2) corners refined as centres of point symmetry (:mod:`.saddle`), and (ny, nx)
    which of them are saddles (:func:`_on_saddle`). A corner that is not is searched again from
    where its row and column predict it (its coarse estimate too far off, as at the edge of a
    strongly distorted board); a corner on the grid's border then over half the disc (its radius
    came from squares extrapolated beyond the grid, which a board trimmed at its squares prints
    smaller), and left out (False) if it still is not."""
    shape = grid.shape
    rho = corner_radii(grid).ravel()
    fit = refine_saddles(gray8, grid.reshape(-1, 2), rho)
    pts = fit.points.copy()
    ok = _on_saddle(fit, fit)
    if ok.all() or not ok.any():
        return pts.reshape(shape), ok.reshape(shape[:2])
    known = pts.copy()
    known[~ok] = np.nan
    pred = grid_predictions(known.reshape(shape)).reshape(-1, 2)
    seed = np.where(np.isfinite(pred), pred, pts)
    # radii again: a corner far off made its neighbours' squares look small
    rho = corner_radii(np.where(ok[:, None], pts, seed).reshape(shape)).ravel()
    border = np.zeros(shape[:2], bool)
    border[[0, -1]] = border[:, [0, -1]] = True
    for shrink, where in ((1.0, np.ones(len(ok), bool)), (0.5, border.ravel())):
        redo = np.flatnonzero(~ok & where)
        if not len(redo):
            continue
        again = refine_saddles(gray8, seed[redo], np.maximum(shrink * rho[redo], MIN_RADIUS))
        good = _on_saddle(again, fit)
        pts[redo[good]] = again.points[good]
        ok[redo[good]] = True
    return pts.reshape(shape), ok.reshape(shape[:2])


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
        seen = np.isfinite(cand[:, 0])
        H, _ = cv2.findHomography(obj[seen], cand[seen])
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
    seen = np.isfinite(centres[..., 0])  # squares with all four corners
    h, w = gray8.shape[:2]
    x = np.clip(np.round(np.where(seen, centres[..., 0], 0)).astype(int), 0, w - 1)
    y = np.clip(np.round(np.where(seen, centres[..., 1], 0)).astype(int), 0, h - 1)
    value = gray8[y, x].astype(float)
    jj, ii = np.mgrid[0:ny - 1, 0:nx - 1]
    dark = ((ii + jj) % 2 == 0) == (board.first_square == "black")  # squares (i + 1, j + 1)
    if value[dark & seen].mean() > value[~dark & seen].mean():
        return corners[::-1].copy()
    return corners
