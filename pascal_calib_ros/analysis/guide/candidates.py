"""Candidate views of a target and the rules that make one feasible.

A candidate is placed as a person would be asked to hold the target: its features' centre on a
pixel, at a distance, its sheet turned to face the camera along that pixel's line of sight and
then tilted by an angle about an in-plane axis, rolled about its normal. The tilt is measured
against the line of sight, not the optical axis: near the border of a wide image the two differ
by 30 degrees and more, and what the detector sees (how flat the ellipses are) is the angle to
the line of sight.

Feasible (:func:`feasibility_problem`): every feature outline point inside the image with a
margin and on a consistent ray of the camera (the lens model does not fold there), the tilt
within what the detector handles for this target (:func:`max_tilt_deg`, measured on renders),
the distance in a range (by default what the captured views span, widened: a person's arm, a
lens's depth of field), and every outer circle's image large enough for the detector (semi-minor
axis at least ``min_radius_px``, its blob threshold; a checkerboard's squares at least
``min_square_px``), and every circle's image an ellipse the detector accepts, with a margin
(:mod:`.candidate_shapes`: radial distortion bends a close ring, or one near the border of a wide
lens, beyond its ellipse and concentric tests). The candidates are tilted 25 or 45 degrees: the
detector finds targets up to 55-70 degrees (:data:`MAX_TILT_DEG`), but steeper views measure worse
and bias more (the edge profiles squeezed, corners' subpixel fits skewed), which no covariance
shows.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from ...detect import BENT_OUTLINE
from ...geometry import Camera, Placement, Transform
from ...targets import Target
from .candidate_shapes import shape_shares

# the largest tilt against the line of sight at which the detector still finds the target in
# most views (measured with `pascal-calib study guided --tilt-limits`, 800x600, blur 1 px)
MAX_TILT_DEG = {"ring": 70.0, "grid": 60.0, "checkerboard": 55.0}
PARTIAL_MIN_SHARE = 0.3  # a marker board's candidate keeps at least this share of its corners in the image
# ... and its markers' bits at least this many px wide where they are smallest: aruco then reads 85-95 %
# of the markers at 25-45 degrees of tilt (charuco_a3 and aprilgrid_a3 renders at 800x600, blur 1 px)
MIN_MODULE_PX = 3.2
# a candidate's circles may use this share of the detector's ellipse limits (:mod:`.candidate_shapes`):
# the rest is for the outline's pixel noise, the person's placement and the estimate's error
SHAPE_SHARE = 0.6
# a single ring past those limits is still measured, along its traced contour, up to BENT_OUTLINE
# times them (detect/contour_edges.py, issue 36): the same share of that
RING_SHAPE_SHARE = SHAPE_SHARE * BENT_OUTLINE


def max_tilt_deg(target: Target) -> float:
    """The detector's tilt limit for this target: the strictest of its feature kinds."""
    kinds = (["grid"] if target.grids else []) + (["ring"] if target.rings or target.discs else []) \
        + (["checkerboard"] if target.boards else [])
    return min(MAX_TILT_DEG[k] for k in kinds) if kinds else MAX_TILT_DEG["ring"]


def outline_points(target: Target, n: int = 24) -> np.ndarray:
    """Points (N, 2) on every outer circle and the corners of every checkerboard and grid
    (target YAML frame): what must stay inside the image."""
    pts = []
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring_disc = [c for c in target.circles[: 2 * len(target.rings) + len(target.discs)] if c.dark_inside]
    for c in ring_disc:
        pts.append(np.stack([c.center[0] + c.radius * np.cos(a), c.center[1] + c.radius * np.sin(a)], 1))
    for g in target.grids:
        for cx, cy in g.centers()[[0, g.cols - 1, -g.cols, -1]]:
            pts.append(np.stack([cx + g.outer_radius * np.cos(a), cy + g.outer_radius * np.sin(a)], 1))
    for b in target.boards:
        x0, y0, x1, y1 = b.extent
        pts.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def feature_centre(target: Target) -> np.ndarray:
    """Centre (2,) of the features' bounding box (target YAML frame)."""
    p = outline_points(target)
    return (p.min(0) + p.max(0)) / 2


def feature_extent(target: Target) -> float:
    """The features' larger bounding-box side (m)."""
    p = outline_points(target)
    return float(np.max(p.max(0) - p.min(0)))


class Candidate(NamedTuple):
    """A candidate view: where the target is asked to be, and its camera_T_target there."""

    placement: Placement
    pose: Transform


def place(target: Target, camera: Camera, p: Placement) -> Transform:
    """camera_T_target (target YAML frame -> camera) of a placement."""
    return place_all(target, camera, [p])[0]


def place_all(target: Target, camera: Camera, placements: list[Placement]) -> list[Transform]:
    """:func:`place` of many placements (one unprojection per distinct pixel); a ValueError if a
    pixel has no ray under this camera."""
    if not placements:
        return []
    return transforms(*place_arrays(target, camera, placements))


def transforms(R: np.ndarray, t: np.ndarray) -> list[Transform]:
    """Transforms of rotation matrices (N, 3, 3) and translations (N, 3)."""
    if not len(R):
        return []
    rots = Rotation.from_matrix(R)
    return [Transform(rots[k], t[k]) for k in range(len(t))]


def place_arrays(target: Target, camera: Camera, placements: list[Placement]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`place_all` as rotation matrices (N, 3, 3) and translations (N, 3)."""
    pix = sorted({p.pixel for p in placements})
    rays = camera.unproject(np.array(pix, float))
    by_pixel = dict(zip(pix, rays, strict=True))
    ray = np.array([by_pixel[p.pixel] for p in placements])
    bad = ~np.all(np.isfinite(ray), 1)
    if bad.any():
        raise ValueError(f"pixel {placements[int(np.argmax(bad))].pixel} has no ray under this camera")
    axis = np.cross([0.0, 0.0, 1.0], ray)
    s_ = np.linalg.norm(axis, axis=1, keepdims=True)
    turn = axis / np.maximum(s_, 1e-300) * np.arctan2(s_, ray[:, 2:3])
    a = np.radians([p.axis_deg for p in placements])
    tilt = np.radians([p.tilt_deg for p in placements])[:, None] * np.c_[np.cos(a), np.sin(a), np.zeros(len(a))]
    roll = np.c_[np.zeros((len(a), 2)), np.radians([p.roll_deg for p in placements])]
    R = rotation_matrices(turn) @ rotation_matrices(tilt) @ rotation_matrices(roll)
    c = feature_centre(target)
    t = np.array([p.distance for p in placements])[:, None] * ray - R @ np.r_[c, 0.0]
    return R, t


def rotation_matrices(rv: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for rotation vectors (N, 3) -> (N, 3, 3)."""
    th = np.linalg.norm(rv, axis=1)
    k = rv / np.maximum(th, 1e-300)[:, None]
    K = np.zeros((len(rv), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def placement_of(target: Target, camera: Camera, pose: Transform) -> Placement:
    """The placement that :func:`place` turns into ``pose`` (its inverse): the features' centre's
    pixel and distance, the tilt against the line of sight, its axis and the roll."""
    c = feature_centre(target)
    centre = pose.apply(np.r_[c, 0.0])
    pixel = camera.project(centre[None])[0]
    ray = centre / np.linalg.norm(centre)
    axis = np.cross([0.0, 0.0, 1.0], ray)
    s_ = float(np.linalg.norm(axis))
    turn = Rotation.from_rotvec(axis / s_ * np.arctan2(s_, float(ray[2]))) if s_ > 1e-12 else Rotation.identity()
    M = (turn.inv() * pose.rotation).as_matrix()  # tilt (about an in-plane axis) then roll (about z)
    z = M[:, 2]
    tilt = float(np.degrees(np.arccos(np.clip(z[2], -1.0, 1.0))))
    # the tilt axis a (in plane) turns z to M z: a ~ z x Mz
    a = np.cross([0.0, 0.0, 1.0], z)
    axis_deg = float(np.degrees(np.arctan2(a[1], a[0]))) if np.linalg.norm(a) > 1e-12 else 0.0
    T = Rotation.from_rotvec(np.radians(tilt) * np.array([np.cos(np.radians(axis_deg)), np.sin(np.radians(axis_deg)),
                                                          0.0]))
    roll = (T.inv() * Rotation.from_matrix(M)).as_rotvec()
    return Placement((float(pixel[0]), float(pixel[1])), float(np.linalg.norm(centre)), tilt, axis_deg,
                     float(np.degrees(roll[2])))


@dataclass(frozen=True)
class Feasibility:
    """The rules of a feasible view (module docstring); distances in metres, angles in degrees."""

    margin_px: float = 10.0
    max_tilt_deg: float = 70.0
    min_distance: float = 0.0
    max_distance: float = np.inf
    min_radius_px: float = 8.0
    min_square_px: float = 7.0
    # the largest share of the detector's ellipse limits a circle's image may use (lens distortion
    # and perspective bend it: :mod:`.candidate_shapes`); inf: not checked
    shape_share: float = SHAPE_SHARE


def default_feasibility(target: Target, width: int, distances: np.ndarray | None = None) -> Feasibility:
    """The rules for this target and image: a margin of 2 % of the width (at least 10 px), the
    detector's tilt limit, distances from 0.6 x the nearest to 1.5 x the farthest captured view."""
    lo, hi = 0.0, np.inf
    if distances is not None and len(distances):
        lo, hi = 0.6 * float(np.min(distances)), 1.5 * float(np.max(distances))
    return Feasibility(margin_px=max(10.0, 0.02 * width), max_tilt_deg=max_tilt_deg(target), min_distance=lo,
                       max_distance=hi, min_radius_px=4.0 if target.grids else 8.0,
                       min_square_px=MIN_MODULE_PX if partial_views_count(target) else 7.0,
                       shape_share=RING_SHAPE_SHARE if target.rings and not target.grids else SHAPE_SHARE)


def line_of_sight_tilt_deg(target: Target, pose: Transform) -> float:
    """Angle (deg) between the sheet's normal and the line of sight to the features' centre."""
    c = feature_centre(target)
    centre = pose.apply(np.r_[c, 0.0])
    n = pose.R[:, 2]
    cosang = float(n @ centre) / max(float(np.linalg.norm(centre)), 1e-12)  # < 0: its back faces the camera
    return float(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))))


def _in_image(camera: Camera, X: np.ndarray, margin: float) -> np.ndarray:
    """Per pose (C,) whether every point of X (C, P, 3) images inside the image with ``margin``
    px to spare, on a consistent ray (the lens model does not fold there)."""
    return np.all(points_in_image(camera, X, margin), axis=1)


def points_in_image(camera: Camera, X: np.ndarray, margin: float) -> np.ndarray:
    """(C, P): which points of X (C, P, 3) image inside the image with ``margin`` px to spare, on a
    consistent ray."""
    C, P, _ = X.shape
    flat = X.reshape(-1, 3)
    ok = np.ones(len(flat), bool) if camera.lens.wide else flat[:, 2] > 1e-6
    uv = np.full((len(flat), 2), np.nan)
    uv[ok] = camera.project(flat[ok])
    back = np.full((len(flat), 3), np.nan)
    fin = np.all(np.isfinite(uv), 1)
    back[fin] = camera.unproject(uv[fin])
    rays = flat / np.linalg.norm(flat, axis=1, keepdims=True)
    good = fin & np.all(np.isfinite(back), 1) & (np.max(np.abs(back - rays), axis=1) <= 1e-6)
    good &= (uv[:, 0] >= margin) & (uv[:, 0] <= camera.width - 1 - margin)
    good &= (uv[:, 1] >= margin) & (uv[:, 1] <= camera.height - 1 - margin)
    return good.reshape(C, P)


def partial_views_count(target: Target) -> bool:
    """Whether a view of ``target`` counts with part of it out of the frame: a marker board alone
    (its corners carry their ids; :mod:`..detect.marker_boards`)."""
    return target.board is not None and target.board.kind != "checkerboard" and not target.circles


def smallest_circles(target: Target) -> tuple[np.ndarray, np.ndarray]:
    """The outer circles (what the detector finds first: a blob's outline) whose images are the
    smallest somewhere: those of the smallest radius at the corners and the middle of the layout
    (centres (K, 2), radii (K,))."""
    outer = [c for c in target.circles if c.dark_inside]
    if not outer:
        return np.zeros((0, 2)), np.zeros(0)
    ctr = np.array([c.center for c in outer])
    rad = np.array([c.radius for c in outer])
    small = rad <= rad.min() * (1 + 1e-9)
    c, r = ctr[small], rad[small]
    lo, hi = c.min(0), c.max(0)
    picks = {int(np.argmin(np.linalg.norm(c - p, axis=1)))
             for p in (lo, hi, (lo[0], hi[1]), (hi[0], lo[1]), (lo + hi) / 2)}
    k = sorted(picks)
    return c[k], r[k]


def smallest_feature_px(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pose (R (C, 3, 3), t (C, 3)): the smallest semi-minor axis of an imaged circle and the
    smallest imaged checkerboard square side, in pixels (inf where the target has none), from 16
    points per circle (:func:`smallest_circles`) and the board's outer squares."""
    C = len(R)
    circ = np.full(C, np.inf)
    ctr, rad = smallest_circles(target)
    if len(ctr):
        a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        xy = ctr[:, None, :] + rad[:, None, None] * np.stack([np.cos(a), np.sin(a)], -1)
        P = np.concatenate([xy, np.zeros((*xy.shape[:2], 1))], -1).reshape(-1, 3)
        q = _project_poses(camera, R, t, P).reshape(C, len(ctr), len(a), 2)
        circ = np.min(np.linalg.norm(q - q.mean(2, keepdims=True), axis=3), axis=(1, 2))
    sq = np.full(C, np.inf)
    for b in target.boards:  # a marker board's bits: scaled from its squares (tags) imaged
        x0, y0, x1, y1 = b.extent
        s = b.corner_spacing
        corners = np.array([[x0, y0], [x1 - s, y0], [x0, y1 - s], [x1 - s, y1 - s]])  # the four corner squares
        P = np.concatenate([np.c_[corners, np.zeros(4)], np.c_[corners + np.array([s, 0.0]), np.zeros(4)],
                            np.c_[corners + np.array([0.0, s]), np.zeros(4)]])
        q = _project_poses(camera, R, t, P).reshape(C, 3, 4, 2)
        sides = np.minimum(np.linalg.norm(q[:, 1] - q[:, 0], axis=2), np.linalg.norm(q[:, 2] - q[:, 0], axis=2))
        sq = np.minimum(sq, sides.min(1) * b.module_size / s)
    return circ, sq


def _project_poses(camera: Camera, R: np.ndarray, t: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Pixels (C, N, 2) of target points P (N, 3) under every pose; NaN behind a pinhole camera."""
    X = np.einsum("cij,nj->cni", R, P) + t[:, None, :]
    flat = X.reshape(-1, 3)
    out = np.full((len(flat), 2), np.nan)
    ok = np.ones(len(flat), bool) if camera.lens.wide else flat[:, 2] > 1e-6
    out[ok] = camera.project(flat[ok])
    return out.reshape(len(R), len(P), 2)


def feasibility_problems(target: Target, camera: Camera, poses: list[Transform], rules: Feasibility) -> list[str]:
    """Per pose (camera_T_target) why a view there is not feasible ("" if it is)."""
    if not poses:
        return []
    return feasibility_problems_of(target, camera, np.stack([p.R for p in poses]),
                                   np.stack([p.translation for p in poses]), rules)


def feasibility_problems_of(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray, rules: Feasibility
                            ) -> list[str]:
    """:func:`feasibility_problems` of poses given as rotation matrices (C, 3, 3) and translations (C, 3)."""
    if not len(R):
        return []
    if partial_views_count(target):  # enough of the board's corners in view
        assert target.board is not None
        pts = target.board.corner_points()
        X = np.einsum("cij,nj->cni", R, np.c_[pts, np.zeros(len(pts))]) + t[:, None, :]
        inside = points_in_image(camera, X, rules.margin_px).mean(axis=1) >= PARTIAL_MIN_SHARE
    else:
        pts = outline_points(target)
        X = np.einsum("cij,nj->cni", R, np.c_[pts, np.zeros(len(pts))]) + t[:, None, :]
        inside = _in_image(camera, X, rules.margin_px)
    c = feature_centre(target)
    centre = R @ np.r_[c, 0.0] + t
    dist = np.linalg.norm(centre, axis=1)
    cosang = np.einsum("ci,ci->c", R[:, :, 2], centre) / np.maximum(dist, 1e-12)  # < 0: its back faces us
    tilt = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0)))
    circ, sq = smallest_feature_px(target, camera, R, t)
    out = []
    for k in range(len(R)):
        if not inside[k]:
            out.append(f"less than {PARTIAL_MIN_SHARE:.0%} of the board's corners in the image (margin "
                       f"{rules.margin_px:g} px)" if partial_views_count(target)
                       else f"the target leaves the image (margin {rules.margin_px:g} px)")
        elif tilt[k] > rules.max_tilt_deg:
            out.append(f"tilted {tilt[k]:.0f} deg against the line of sight (the detector handles "
                       f"{rules.max_tilt_deg:g})")
        elif not rules.min_distance <= dist[k] <= rules.max_distance:
            out.append(f"distance {dist[k]:.2f} m outside {rules.min_distance:.2f}-{rules.max_distance:.2f} m")
        elif not circ[k] >= rules.min_radius_px:
            out.append(f"circles too small ({circ[k]:.1f} px semi-minor axis, need {rules.min_radius_px:g})")
        elif not sq[k] >= rules.min_square_px:
            what = "checkerboard squares" if target.checkerboard is not None else "the markers' bits"
            out.append(f"{what} too small ({sq[k]:.1f} px, need {rules.min_square_px:g})")
        else:
            out.append("")
    return _shape_problems(target, camera, R, t, rules, out)


def _shape_problems(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray, rules: Feasibility,
                    problems: list[str]) -> list[str]:
    """``problems`` with the poses found feasible so far checked for the circles' shapes: each
    circle's image an ellipse the detector accepts, within ``rules.shape_share`` of its limits
    (:func:`.candidate_shapes.shape_shares`)."""
    ok = [k for k, why in enumerate(problems) if not why]
    if not ok or not np.isfinite(rules.shape_share):
        return problems
    out = list(problems)
    for k, share in zip(ok, shape_shares(target, camera, R[ok], t[ok]), strict=True):
        if not share <= rules.shape_share:
            out[k] = (f"the circles' images are not ellipses the detector accepts (lens distortion and "
                      f"perspective: {share:.0%} of its limit, {rules.shape_share:.0%} allowed)")
    return out


def feasibility_problem(target: Target, camera: Camera, pose: Transform, rules: Feasibility) -> str:
    """Why a view at ``pose`` (camera_T_target) is not feasible ("" if it is)."""
    return feasibility_problems(target, camera, [pose], rules)[0]


def distance_for_size(target: Target, camera: Camera, size_fraction: float) -> float:
    """Distance (m) at which the features' extent spans ``size_fraction`` of the image width
    (head-on, at the image centre)."""
    return float(camera.K[0, 0] * feature_extent(target) / (size_fraction * camera.width))


@dataclass(frozen=True)
class CandidateGrid:
    """The placements tried: the features' centre on a cols x rows grid of pixels spanning
    ``span`` of the image, at each size (fraction of the width), head-on and tilted by each of
    ``tilts_deg`` about ``axes`` directions, each at the rolls given."""

    cols: int = 5
    rows: int = 4
    span: float = 0.8
    sizes: tuple[float, ...] = (0.25, 0.35, 0.5)
    tilts_deg: tuple[float, ...] = (25.0, 45.0)
    axes: int = 8
    rolls_deg: tuple[float, ...] = (0.0,)


def candidate_placements(camera: Camera, grid: CandidateGrid, target: Target) -> list[Placement]:
    """Every placement of the grid (not yet checked for feasibility)."""
    us = camera.width * (0.5 + grid.span * (np.arange(grid.cols) / max(grid.cols - 1, 1) - 0.5))
    vs = camera.height * (0.5 + grid.span * (np.arange(grid.rows) / max(grid.rows - 1, 1) - 0.5))
    out = []
    for v, u, size, roll in itertools.product(vs, us, grid.sizes, grid.rolls_deg):
        d = distance_for_size(target, camera, size)
        out.append(Placement((float(u), float(v)), d, 0.0, 0.0, roll))
        for tilt, k in itertools.product(grid.tilts_deg, range(grid.axes)):
            out.append(Placement((float(u), float(v)), d, tilt, 360.0 * k / grid.axes, roll))
    return out


def with_ray(camera: Camera, placements: list[Placement]) -> list[Placement]:
    """The placements whose pixel has a ray under ``camera``."""
    pix = sorted({p.pixel for p in placements})
    rays = camera.unproject(np.array(pix, float)) if pix else np.zeros((0, 3))
    has_ray = {q for q, r in zip(pix, rays, strict=True) if np.all(np.isfinite(r))}
    return [p for p in placements if p.pixel in has_ray]


def feasible_candidates(target: Target, camera: Camera, placements: list[Placement], rules: Feasibility
                        ) -> list[Candidate]:
    """The placements whose pose passes the rules (:func:`feasibility_problems`), with their poses."""
    ok = with_ray(camera, placements)
    poses = place_all(target, camera, ok)
    problems = feasibility_problems(target, camera, poses, rules)
    return [Candidate(p, pose) for p, pose, why in zip(ok, poses, problems, strict=True) if not why]


def partial_placements(camera: Camera, target: Target) -> list[Placement]:
    """For a marker board (:func:`partial_views_count`): the board's centre on the image's corners
    and the middles of its sides, large (60 and 80 % of the width), head-on and tilted 25 degrees
    about four axes: views that reach the image's corners with part of the board out of the frame,
    where a whole board cannot go and where the lens model is decided."""
    if not partial_views_count(target):
        return []
    w, h = camera.width, camera.height
    out = []
    for (u, v), size in itertools.product([(a * w, b * h) for a in (0.0, 0.5, 1.0) for b in (0.0, 0.5, 1.0)
                                           if (a, b) != (0.5, 0.5)], (0.6, 0.8)):
        d = distance_for_size(target, camera, size)
        out.append(Placement((float(u), float(v)), d, 0.0, 0.0, 0.0))
        out += [Placement((float(u), float(v)), d, 25.0, 90.0 * k, 0.0) for k in range(4)]
    return out


def _distance_for_bits(target: Target, camera: Camera, tilt_deg: float) -> float:
    """The distance at which the target's smallest bits image ``MIN_MODULE_PX`` + 25 % at this tilt
    (head-on at the image centre, the far side of the board foreshortened by about cos(tilt))."""
    assert target.board is not None
    far = feature_extent(target) / 2 * np.sin(np.radians(tilt_deg))
    return float(camera.K[0, 0] * target.board.module_size * np.cos(np.radians(tilt_deg))
                 / (1.25 * MIN_MODULE_PX)) - far


def bootstrap_placements(camera: Camera, target: Target) -> list[Placement]:
    """Three fixed views to start from, before any covariance exists: near the middle, at about
    45 % of the width, tilted 35 degrees about three different axes (the closed forms need tilted
    views; Zhang's method needs the planes' normals to differ)."""
    w, h = camera.width, camera.height
    d = distance_for_size(target, camera, 0.45)
    if partial_views_count(target):  # as near as the markers' bits need (they may leave the frame)
        d = min(d, _distance_for_bits(target, camera, 35.0))
    return [Placement((0.5 * w, 0.5 * h), d, 35.0, 0.0, 0.0),
            Placement((0.4 * w, 0.45 * h), d, 35.0, 90.0, 10.0),
            Placement((0.6 * w, 0.55 * h), d, 35.0, 225.0, -10.0)]
