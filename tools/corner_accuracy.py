#!/usr/bin/env python3
"""Checkerboard corners, corner by corner: our detector against OpenCV's two.

- ours: ``detect.checkerboard.find_checkerboard`` (board found on a reduced copy, every corner
  refined at full resolution with its own ``cornerSubPix`` window, checked against the image);
- classic: ``cv2.findChessboardCorners`` (adaptive threshold, normalised) then ``cv2.cornerSubPix``
  with an 11x11 half-window, 30 iterations, eps 0.001, as OpenCV's calibration tutorial does it;
- SB: ``cv2.findChessboardCornersSB`` with ``CALIB_CB_EXHAUSTIVE | CALIB_CB_ACCURACY``.

Renders (``sim.session``, exact corners from the true pose and lens; conditions: plain, k1 -0.3,
blur 2.5 px, JPEG 75, and a board trimmed at its squares as in OpenCV's sample photos): RMS and
largest error against the truth of every detector over the corners it returned (a corner our
check rejects counts as a rejection, not in the errors) and the median CPU time per frame (one
OpenCV thread, so that a loaded machine does not distort the comparison). Photos (``--photos DIR --board
YAML``, any board): the pairwise distances of the three, their median and largest, our corners'
distance where OpenCV's two agree, and the corners our check rejects.

``--check``: the corner check's statistic on clean corners (renders, photos) and what the check
does with corners spoiled by an occluder, a smudge or a glare drawn over them.

Run: .venv/bin/python tools/corner_accuracy.py [--quick] [--photos DIR --board YAML] [--check]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from pascal_calib_ros.detect.checkerboard import find_checkerboard
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.io.images import read_grey
from pascal_calib_ros.sim.render import RenderedView
from pascal_calib_ros.sim.session import SessionSpec, render_session_views, session_views
from pascal_calib_ros.studies.bench import bench_frames
from pascal_calib_ros.targets import Checkerboard, Target, resolve_target

SIZES = ((640, 480), (800, 600), (1920, 1080), (2456, 2058))
CONDITIONS: dict[str, dict[str, float]] = {  # SessionSpec fields on top of the defaults (blur 1 px, noise 1.5)
    "plain": {},
    "k1 -0.3": {"k1": -0.3},
    "blur 2.5": {"blur": 2.5},
    "jpeg 75": {"jpeg": 75},
    "cut": {},  # the outer squares cut by the sheet's edge, see cut_board()
}
CUT_TO, MARGIN_TO = 0.4, 0.3  # "cut": the last row and column of squares keep this fraction of their
# size, and the sheet ends this fraction of a square beyond them
TUTORIAL_WINDOW = (11, 11)
TUTORIAL_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
AGREE_PX = 0.5  # OpenCV's two detectors "agree" on a corner when they are this close (px)

Corners = np.ndarray | None
Finder = Callable[[np.ndarray, Target], Corners]


def ours(gray8: np.ndarray, target: Target) -> Corners:
    """(N, 2) corners in target order, NaN rows for corners the check rejected; None if not found."""
    det = Detection(gray8.shape[1], gray8.shape[0])
    return find_checkerboard(gray8, target, det)


def classic(gray8: np.ndarray, target: Target) -> Corners:
    assert target.checkerboard is not None
    found, c = cv2.findChessboardCorners(gray8, target.checkerboard.inner_corners,
                                         flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found or c is None:
        return None
    c = cv2.cornerSubPix(gray8, c, TUTORIAL_WINDOW, (-1, -1), TUTORIAL_CRITERIA)
    return np.asarray(c, float).reshape(-1, 2)


def sb(gray8: np.ndarray, target: Target) -> Corners:
    assert target.checkerboard is not None
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, c = cv2.findChessboardCornersSB(gray8, target.checkerboard.inner_corners, flags=flags)
    if not found or c is None:
        return None
    return np.asarray(c, float).reshape(-1, 2)


DETECTORS: dict[str, Finder] = {"ours": ours, "classic": classic, "SB": sb}


def orderings(corners: np.ndarray, nx: int, ny: int) -> list[np.ndarray]:
    """The grid's four orders that keep rows as rows: as found, reversed, rows flipped, columns
    flipped (OpenCV's order may start from either end and either handedness)."""
    g = corners.reshape(ny, nx, 2)
    return [g.reshape(-1, 2), g[::-1, ::-1].reshape(-1, 2), g[::-1].reshape(-1, 2), g[:, ::-1].reshape(-1, 2)]


def aligned(corners: np.ndarray, reference: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """``corners`` in the order of ``reference`` (the ordering closest to it; NaN rows ignored)."""
    def cost(c: np.ndarray) -> float:
        return float(np.nanmedian(np.linalg.norm(c - reference, axis=1)))
    return min(orderings(corners, nx, ny), key=cost)


@dataclass(frozen=True)
class _TrimmedBoard(Checkerboard):
    """A checkerboard whose last column and row of squares are printed only ``keep`` of their size."""

    keep: float = 1.0

    @property
    def extent(self) -> tuple[float, float, float, float]:
        x0, y0, x1, y1 = super().extent
        cut = (1 - self.keep) * self.square_size
        return (x0, y0, x1 - cut, y1 - cut)


def cut_board(target: Target) -> Target:
    """The target with its last row and column of squares trimmed to ``CUT_TO`` of their size and
    the sheet ending ``MARGIN_TO`` of a square beyond them, the background after that: a board
    trimmed as the one in OpenCV's sample photos (its bottom row and right column are narrower
    than the others, a white strip and the board's edge follow)."""
    b = target.checkerboard
    assert b is not None
    trimmed = _TrimmedBoard(b.origin, b.squares, b.square_size, b.first_square, keep=CUT_TO)
    _, _, x1, y1 = trimmed.extent
    margin = MARGIN_TO * b.square_size
    return replace(target, sheet=(x1 + margin, y1 + margin), boards=(trimmed,))


def truth(target: Target, view: RenderedView) -> np.ndarray:
    """Exact image of the inner corners: the sheet points through the true pose and lens."""
    assert target.checkerboard is not None and view.pose is not None
    P = target.checkerboard.corner_points()
    X = np.c_[P, np.zeros(len(P))] @ view.pose.R.T + view.pose.t
    return view.camera.project(X)


def render_views(target: Target, spec: SessionSpec) -> list[RenderedView]:
    """The session's views (through the bench's fast path without distortion: the same pixels)."""
    if spec.k1:
        return render_session_views(target, spec)[1]
    cam = spec.camera()
    imgs = bench_frames(target, spec)
    return [RenderedView(img, cam, pose, sensor, target.name)
            for img, (_, pose, sensor) in zip(imgs, session_views(target, spec), strict=True)]


@dataclass
class Score:
    errors: list[np.ndarray]
    times: list[float]
    missed: int = 0  # views where the board was not found
    rejected: int = 0  # corners returned as NaN

    def line(self) -> str:
        e = np.concatenate(self.errors) if self.errors else np.zeros(0)
        t = 1000 * float(np.median(self.times)) if self.times else float("nan")
        if not len(e):
            return f"{'-':>7} {'-':>6} {t:7.1f}"
        extra = (f" miss {self.missed}" if self.missed else "") + (f" rej {self.rejected}" if self.rejected else "")
        return f"{np.sqrt(np.mean(e**2)):7.3f} {e.max():6.2f} {t:7.1f}{extra}"


def score_views(views: list[RenderedView], target: Target, finders: dict[str, Finder]) -> dict[str, Score]:
    """Per detector: errors (px) of every corner it returned against the truth, and times (s)."""
    assert target.checkerboard is not None
    nx, ny = target.checkerboard.inner_corners
    scores = {name: Score([], []) for name in finders}
    for v in views:
        t_true = truth(target, v)
        for name, fn in finders.items():
            t0 = time.process_time()
            c = fn(v.image, target)
            scores[name].times.append(time.process_time() - t0)
            if c is None:
                scores[name].missed += 1
                continue
            c = aligned(c, t_true, nx, ny)
            ok = np.isfinite(c[:, 0])
            scores[name].rejected += int((~ok).sum())
            scores[name].errors.append(np.linalg.norm(c[ok] - t_true[ok], axis=1))
    return scores


def render_table(quick: bool, finders: dict[str, Finder] = DETECTORS, views: int = 0) -> None:
    names = list(finders)
    print("renders: error against the truth, px (RMS, max) and median CPU time per frame, ms (one thread);\n"
          "miss: views where the board was not found, rej: corners our check returned as NaN")
    head = "".join(f" | {n + ': rms':>11} {'max':>6} {'ms':>7}" for n in names)
    print(f"{'target':<16} {'size':>9} {'condition':<9}{head}")
    for tname in ("checkerboard_a4", "pascal_board_a3"):
        for w, h in SIZES[:2] if quick else SIZES:
            for cname, extra in CONDITIONS.items():
                target = resolve_target(tname)
                target = cut_board(target) if cname == "cut" else target
                n = views or (2 if quick else 4)
                spec = SessionSpec(width=w, height=h, views=n, seed=11, **extra)  # type: ignore[arg-type]
                s = score_views(render_views(target, spec), target, finders)
                cells = "".join(f" | {s[k].line():>26}" for k in names)
                print(f"{tname:<16} {f'{w}x{h}':>9} {cname:<9}{cells}", flush=True)


def _pair(a: Corners, b: Corners) -> np.ndarray:
    if a is None or b is None:
        return np.full(1, np.nan)
    return np.linalg.norm(a - b, axis=1)


def _calibration_rms(obj: np.ndarray, views: list[np.ndarray], size: tuple[int, int]) -> tuple[float, float]:
    """RMS and largest reprojection residual (px) of ``cv2.calibrateCamera`` (5 coefficients) on
    the given corners (NaN rows left out): how consistent the corners are with one camera."""
    op = [np.c_[obj, np.zeros(len(obj))][np.isfinite(v[:, 0])].astype(np.float32) for v in views]
    ip = [v[np.isfinite(v[:, 0])].astype(np.float32).reshape(-1, 1, 2) for v in views]
    rms, K, D, rv, tv = cv2.calibrateCamera(op, ip, size, None, None)
    worst = max(float(np.max(np.linalg.norm(cv2.projectPoints(o, r, t, K, D)[0].reshape(-1, 2) - i.reshape(-1, 2),
                                            axis=1))) for o, i, r, t in zip(op, ip, rv, tv, strict=True))
    return float(rms), worst


def photo_table(photos: Path, board: Path) -> None:
    target = resolve_target(str(board))
    assert target.checkerboard is not None, f"{board} has no checkerboard"
    nx, ny = target.checkerboard.inner_corners
    files = sorted(p for p in photos.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png", ".bmp", ".tif"))
    print(f"photos: pairwise distances, px (median / max); 'ours vs both': our distance to the mean of\n"
          f"OpenCV's two where they agree to {AGREE_PX} px (median / max, over how many corners)")
    print(f"{'photo':<14} {'ours-classic':>13} {'ours-SB':>13} {'classic-SB':>13} {'ours vs both':>20}  "
          "rejected by our check")
    found: dict[str, list[np.ndarray]] = {name: [] for name in DETECTORS}
    size = (0, 0)
    for f in files:
        g = np.clip(read_grey(str(f)), 0, 255).astype(np.uint8)
        size = (g.shape[1], g.shape[0])
        det = Detection(g.shape[1], g.shape[0])
        o = find_checkerboard(g, target, det)
        c, s = classic(g, target), sb(g, target)
        ref = o if o is not None else c
        if ref is not None:
            c = None if c is None else aligned(c, ref, nx, ny)
            s = None if s is None else aligned(s, ref, nx, ny)
        cells = []
        for a, b in ((o, c), (o, s), (c, s)):
            d = _pair(a, b)
            cells.append("-" if np.all(np.isnan(d)) else f"{np.nanmedian(d):.3f}/{np.nanmax(d):.2f}")
        both = "-"
        if o is not None and c is not None and s is not None:
            agree = (_pair(c, s) < AGREE_PX) & np.isfinite(o[:, 0])
            d = np.linalg.norm(o[agree] - (c[agree] + s[agree]) / 2, axis=1)
            both = f"{np.median(d):.3f}/{d.max():.2f} ({agree.sum()})"
            for name, v in (("ours", o), ("classic", c), ("SB", s)):
                found[name].append(v)
        rej = "not found" if o is None else (det.note or "none")
        print(f"{f.name:<14} {cells[0]:>13} {cells[1]:>13} {cells[2]:>13} {both:>20}  {rej}", flush=True)
    if len(found["ours"]) >= 3:
        obj = target.checkerboard.corner_points()
        print(f"cv2.calibrateCamera on each detector's corners ({len(found['ours'])} photos found by all three): "
              "reprojection RMS / largest residual, px")
        cells = [(name, *_calibration_rms(obj, v, size)) for name, v in found.items()]
        print("  " + "   ".join(f"{name}: {rms:.4f} / {worst:.3f}" for name, rms, worst in cells))


def _spoiled(img: np.ndarray, at: np.ndarray, kind: str, size: float, rng: np.random.Generator) -> np.ndarray:
    """``img`` with an occluding disc of radius ``size`` (a random grey), a smudge (darkened by up
    to 60 %, Gaussian of sigma ``size``) or a glare (+180 grey levels at most, sigma ``size``) at ``at``."""
    h, w = img.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    r2 = (xx - at[0]) ** 2 + (yy - at[1]) ** 2
    out = img.astype(float)
    if kind == "occluder":
        cover = np.clip(size - np.sqrt(r2) + 0.5, 0, 1)
        out = out * (1 - cover) + rng.uniform(30, 200) * cover
    elif kind == "smudge":
        out *= 1 - 0.6 * np.exp(-r2 / (2 * size**2))
    else:
        out += 180 * np.exp(-r2 / (2 * size**2))
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def _clean_ratios(img: np.ndarray, target: Target, exact: np.ndarray | None = None) -> np.ndarray | None:
    """Asymmetry of the corners of a clean view over the board's lower quartile (the check's
    statistic; it rejects above ``MAX_ASYMMETRY``) after the first refinement; with the ``exact``
    corners, only of those refined to within 0.1 px of them (the others are searched again)."""
    from pascal_calib_ros.detect.checkerboard import coarse_corners, corner_radii, right_handed
    from pascal_calib_ros.detect.saddle import refine_saddles

    assert target.checkerboard is not None
    nx, ny = target.checkerboard.inner_corners
    c = coarse_corners(img, (nx, ny))
    if c is None:
        return None
    grid = right_handed(c.reshape(ny, nx, 2))
    fit = refine_saddles(img, grid.reshape(-1, 2), corner_radii(grid).ravel())
    ratio = fit.rms / np.percentile(fit.rms, 25)
    if exact is None:
        return ratio
    return ratio[np.linalg.norm(fit.points - aligned(exact, fit.points, nx, ny), axis=1) < 0.1]


def check_table(photos: Path | None, board: Path | None, trials: int = 15) -> None:
    """The corner check: its statistic on clean corners, and what it does with spoiled ones
    (imports of this branch's detector here: the tables above also run against an older one)."""
    from pascal_calib_ros.detect.checkerboard import MAX_ASYMMETRY

    print(f"corner check: asymmetry / board's lower quartile on clean corners (rejected above {MAX_ASYMMETRY});\n"
          "renders: the corners refined to within 0.1 px of the truth; photos: all")
    cases = [("checkerboard_a4", 640, 480), ("checkerboard_a4", 800, 600), ("pascal_board_a3", 1920, 1080)]
    for cname, extra in CONDITIONS.items():
        ratios = []
        for tname, w, h in cases:
            target = resolve_target(tname)
            target = cut_board(target) if cname == "cut" else target
            spec = SessionSpec(width=w, height=h, views=3, seed=5, **extra)  # type: ignore[arg-type]
            ratios += [r for v in render_views(target, spec)
                       if (r := _clean_ratios(v.image, target, truth(target, v))) is not None]
        x = np.concatenate(ratios)
        print(f"  renders {cname:<9} {len(x):5d} corners: median {np.median(x):.2f}  p99 {np.percentile(x, 99):.2f}  "
              f"max {x.max():.2f}")
    if photos is not None and board is not None:
        target = resolve_target(str(board))
        files = sorted(p for p in photos.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png", ".bmp", ".tif"))
        found = [r for f in files if (r := _clean_ratios(np.clip(read_grey(str(f)), 0, 255).astype(np.uint8),
                                                          target)) is not None]
        if found:
            x = np.concatenate(found)
            print(f"  photos            {len(x):5d} corners: median {np.median(x):.2f}  p99 "
                  f"{np.percentile(x, 99):.2f}  max {x.max():.2f}")
    _spoil_table(cases, trials)


def _spoil_table(cases: list[tuple[str, int, int]], trials: int) -> None:
    from pascal_calib_ros.detect.checkerboard import corner_clearance, corner_radii, saddle_grid
    from pascal_calib_ros.detect.saddle import refine_saddles

    print(f"spoiled corners ({trials} per view, 3 views per case: {', '.join(f'{t} {w}x{h}' for t, w, h in cases)};\n"
          "size 0.15-0.6 and offset 0-0.8 of the corner's clearance; refined from the truth + 0.5 px noise)")
    rng = np.random.default_rng(2)
    rows: dict[str, list[tuple[float, bool, float, int, int]]] = {"occluder": [], "smudge": [], "glare": []}
    for tname, w, h in cases:
        target = resolve_target(tname)
        assert target.checkerboard is not None
        nx, ny = target.checkerboard.inner_corners
        for v in render_views(target, SessionSpec(width=w, height=h, views=3, seed=5)):
            t = truth(target, v).reshape(ny, nx, 2)
            for trial in range(trials):
                j, i = int(rng.integers(0, ny)), int(rng.integers(0, nx))
                clear = corner_clearance(t)[j, i]
                kind = list(rows)[trial % 3]
                size, angle = rng.uniform(0.15, 0.6) * clear, rng.uniform(0, 2 * np.pi)
                at = t[j, i] + rng.uniform(0, 0.8) * clear * np.array([np.cos(angle), np.sin(angle)])
                img = _spoiled(v.image, at, kind, size, rng)
                start = t + rng.normal(0, 0.5, t.shape)
                pts, ok = saddle_grid(img, start)
                first = refine_saddles(img, start.reshape(-1, 2), corner_radii(start).ravel()).points.reshape(t.shape)
                e, e_first = np.linalg.norm(pts - t, axis=2), np.linalg.norm(first - t, axis=2)
                others = np.ones((ny, nx), bool)
                others[j, i] = False
                moved = int(np.sum(~ok & others & (e_first > 0.1)))
                rows[kind].append((float(e[j, i]), bool(ok[j, i]), float(e[others & ok].max()),
                                   int(np.sum(~ok & others)), moved))
    print(f"  {'spoil':<9} {'n':>3} {'rejected':>8} {'kept >0.2 px':>12} {'kept >0.5 px':>12} {'worst kept':>10}   "
          "other corners: rejected (of them moved > 0.1 px by the spoil), worst kept")
    for kind, r in rows.items():
        kept = [x[0] for x in r if x[1]]
        print(f"  {kind:<9} {len(r):3d} {len(r) - len(kept):8d} {sum(k > 0.2 for k in kept):12d} "
              f"{sum(k > 0.5 for k in kept):12d} {max(kept, default=0):10.2f}   "
              f"{sum(x[3] for x in r)} ({sum(x[4] for x in r)}), {max(x[2] for x in r):.2f} px")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="640x480 and 800x600 only, 2 views per case")
    ap.add_argument("--photos", type=Path, help="a directory of photos of one checkerboard")
    ap.add_argument("--board", type=Path, help="the target YAML of that checkerboard (with --photos)")
    ap.add_argument("--no-renders", action="store_true", help="only the photos")
    ap.add_argument("--check", action="store_true", help="the corner check's study: clean and spoiled corners")
    a = ap.parse_args()
    cv2.setNumThreads(1)  # CPU time of one thread: comparable on a shared machine
    if (a.photos is None) != (a.board is None):
        ap.error("--photos and --board go together")
    if a.photos is not None and not a.photos.is_dir():
        ap.error(f"{a.photos} is not a directory")
    if a.check:
        check_table(a.photos, a.board)
        return 0
    if not a.no_renders:
        render_table(a.quick)
    if a.photos is not None:
        photo_table(a.photos, a.board)
    return 0


if __name__ == "__main__":
    sys.exit(main())
