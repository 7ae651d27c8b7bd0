"""Rank feasible candidate views by the projection uncertainty over the whole image that would
follow each (:mod:`.guidance`), and return the best few, different enough from one another that
skipping one (an arm cannot reach it, a person cannot hold it) leaves real alternatives.

Two passes keep a suggestion within a second: every feasible candidate with a thinned synthetic
view (a few points per edge standing for all of them) on a coarse grid of pixels, then the best
of those exactly (every point the pipeline would keep, the full grid).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ...calibrate import CalibrationOptions, PlanePose, RefineResult, pose_to_params
from ...geometry import Camera, ImageSize, Transform
from ...targets import Target
from .candidates import (
    Candidate,
    CandidateGrid,
    Feasibility,
    Placement,
    candidate_placements,
    default_feasibility,
    feasible_candidates,
    feature_centre,
    partial_placements,
    placement_of,
)
from .guidance import ChainRows, Linearisation, Prediction, ViewPredictor
from .view_synthesis import synthesise_views

COARSE_POINTS = 24  # points per edge in the first pass
COARSE_GRID = 4  # every 4th row and column of the pixel grid in the first pass
COARSE_ELEMENTS = 12  # grid elements in the first pass


@dataclass(frozen=True)
class RankedView:
    """A candidate with its predicted worst projection sigma over the image (px)."""

    pose: Transform  # camera_T_target: target YAML frame -> camera optical frame
    placement: Placement
    predicted_sigma_px: float
    readout_cov: np.ndarray = field(repr=False)  # covariance of (free intrinsics, w, tau, extra)
    score: float = float("nan")  # what was ranked on (lower is better)


def local_pose(target: Target, pose: Transform) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the refinement's local frame (origin at the first circle's centre) -> camera."""
    o = np.array(target.local_origin)
    return pose.R, pose.translation + pose.R @ np.r_[o, 0.0]


def yaml_pose(target: Target, R: np.ndarray, t: np.ndarray) -> Transform:
    """camera_T_target (YAML frame) of a local-frame pose (R, t)."""
    o = np.array(target.local_origin)
    return Transform.from_rt(R, t - R @ np.r_[o, 0.0])


def predict_poses(pred: ViewPredictor, target: Target, poses: list[Transform], options: CalibrationOptions,
                  coarse: bool = False, chain: ChainRows | None = None) -> Prediction:
    """:meth:`ViewPredictor.predict` for views of ``target`` at ``poses`` (camera_T_target)."""
    if not poses:
        return pred.predict([], np.zeros((0, pred.prob.dof)), [], COARSE_GRID if coarse else 1, chain)
    Rt = [local_pose(target, pose) for pose in poses]
    R, t = np.stack([r for r, _ in Rt]), np.stack([t for _, t in Rt])
    synth = synthesise_views(target, pred.camera_sized, R, t, options, COARSE_POINTS if coarse else 0,
                             COARSE_ELEMENTS if coarse else 0)
    params = np.array([pose_to_params(PlanePose(Ri, ti), pred.prob.dof) for Ri, ti in Rt])
    return pred.predict([sv.data for sv in synth], params, [sv.weight for sv in synth], COARSE_GRID if coarse else 1,
                        chain)


DISTINCT_TILT_DEG = 20.0  # tilts (as vectors: magnitude along the axis' direction) this far apart differ


def distinct(a: Placement, b: Placement, size: ImageSize, roll_deg: float = 0.0) -> bool:
    """Whether two views differ enough to be offered side by side: centres 15 % of the image
    diagonal apart, or distances 30 % apart, or tilts :data:`DISTINCT_TILT_DEG` apart (the tilt
    as a vector, its length the angle, its direction the axis', so that a head-on view and one
    tilted 25 degrees differ, and two views tilted 25 degrees about axes 60 degrees apart), or,
    with ``roll_deg`` > 0, rolls about the sheet's normal more than ``roll_deg`` apart (for an arm
    a view turned about the optical axis is a new motion, the one the hand-eye rotation needs)."""
    width, height = size
    if np.hypot(a.pixel[0] - b.pixel[0], a.pixel[1] - b.pixel[1]) > 0.15 * np.hypot(width, height):
        return True
    if abs(np.log(a.distance / b.distance)) > np.log(1.3):
        return True
    if roll_deg > 0 and abs((a.roll_deg - b.roll_deg + 180.0) % 360.0 - 180.0) > roll_deg:
        return True
    ta = a.tilt_deg * np.array([np.cos(np.radians(a.axis_deg)), np.sin(np.radians(a.axis_deg))])
    tb = b.tilt_deg * np.array([np.cos(np.radians(b.axis_deg)), np.sin(np.radians(b.axis_deg))])
    return bool(np.linalg.norm(ta - tb) > DISTINCT_TILT_DEG)


def pick_distinct(ranked: list[RankedView], n: int, size: ImageSize, roll_deg: float = 0.0
                  ) -> list[RankedView]:
    """The best ``n`` of ``ranked`` (sorted best first), each distinct from those before it
    (:func:`distinct`, with ``roll_deg``)."""
    out: list[RankedView] = []
    for r in ranked:
        if all(distinct(r.placement, o.placement, size, roll_deg) for o in out):
            out.append(r)
        if len(out) == n:
            break
    return out


Scorer = Callable[[Prediction, list[int]], np.ndarray]


def rank_candidates(pred: ViewPredictor, target: Target, candidates: list[Candidate], n: int,
                    options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                    score: Scorer | None = None, chain_of: Callable[[list[int]], ChainRows] | None = None,
                    roll_deg: float = 0.0) -> list[RankedView]:
    """The ``n`` best distinct candidates by ``score`` (default: the predicted worst projection
    sigma), the two passes of the module docstring. ``chain_of(indices)`` gives the robot chain
    rows (:class:`.guidance.ChainRows`) of those candidates, if any; ``roll_deg`` > 0 counts views
    rolled that far apart as distinct (:func:`distinct`: an arm's wrist turn)."""
    if not candidates:
        return []
    score = score or (lambda p, idx: p.sigma_px)
    poses = [c.pose for c in candidates]
    idx = list(range(len(candidates)))
    first = predict_poses(pred, target, poses, options, coarse=True, chain=chain_of(idx) if chain_of else None)
    order = np.argsort(score(first, idx), kind="stable")
    keep = [int(i) for i in order[: max(4 * n, 12)]]
    exact = predict_poses(pred, target, [poses[i] for i in keep], options,
                          chain=chain_of(keep) if chain_of else None)
    s = score(exact, keep)
    ranked = [RankedView(poses[i], candidates[i].placement, float(exact.sigma_px[j]), exact.readout_cov[j], float(s[j]))
              for j, i in enumerate(keep)]
    ranked.sort(key=lambda r: r.score)
    return pick_distinct(ranked, n, pred.size, roll_deg)


@dataclass(frozen=True)
class ViewSuggestions:
    """The projection uncertainty now and the best next views."""

    sigma_px: float  # worst projection sigma over the whole image now (the real one)
    distance: float  # m, the views' median distance it is evaluated at
    suggestions: list[RankedView]
    n_candidates: int  # feasible candidates ranked
    camera: Camera


def view_distances(target: Target, res: RefineResult) -> np.ndarray:
    """Distances (m) of the views' feature centres from the camera."""
    assert res.x is not None and res.problem is not None and res.intr0 is not None
    R, t = res.view_poses_of(res.x)
    o = np.array(target.local_origin)
    c = np.r_[feature_centre(target) - o, 0.0]
    return np.linalg.norm(R @ c + t, axis=1)


def captured_placements(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray) -> list[Placement]:
    """The placements (:func:`.candidates.placement_of`) of the captured views' poses (local
    frame, R (V, 3, 3), t (V, 3))."""
    return [placement_of(target, camera, yaml_pose(target, Ri, ti)) for Ri, ti in zip(R, t, strict=True)]


def unseen(candidates: list[Candidate], seen: list[Placement], size: ImageSize,
           roll_deg: float = 0.0) -> list[Candidate]:
    """The candidates distinct (:func:`distinct`) from every captured view. The covariance knows
    only the noise that averages out; a view taken again where one was taken repeats that view's
    detection biases (which do not), so the guide offers something new."""
    if not candidates or not seen:
        return list(candidates)
    new = distinct_from_all([c[0] for c in candidates], seen, size, roll_deg)
    return [c for c, keep in zip(candidates, new, strict=True) if keep]


def distinct_from_all(a: list[Placement], b: list[Placement], size: ImageSize, roll_deg: float = 0.0
                      ) -> np.ndarray:
    """Per placement of ``a`` whether it is :func:`distinct` from every one of ``b`` (all pairs at once)."""
    width, height = size

    def arrays(ps: list[Placement]) -> tuple[np.ndarray, ...]:
        ax = np.radians([p.axis_deg for p in ps])
        tilt = np.array([p.tilt_deg for p in ps])[:, None] * np.c_[np.cos(ax), np.sin(ax)]
        return (np.array([p.pixel for p in ps], float), np.array([p.distance for p in ps]),
                np.array([p.roll_deg for p in ps]), tilt)

    (pa, da, ra, ta), (pb, db, rb, tb) = arrays(a), arrays(b)
    d = (np.hypot(pa[:, None, 0] - pb[None, :, 0], pa[:, None, 1] - pb[None, :, 1]) > 0.15 * np.hypot(width, height))
    d |= np.abs(np.log(da[:, None] / db[None, :])) > np.log(1.3)
    if roll_deg > 0:
        d |= np.abs((ra[:, None] - rb[None, :] + 180.0) % 360.0 - 180.0) > roll_deg
    d |= np.linalg.norm(ta[:, None, :] - tb[None, :, :], axis=2) > DISTINCT_TILT_DEG
    return np.all(d, axis=1)


def suggest_views(res: RefineResult, target: Target, size: ImageSize, n: int = 5,
                  grid: CandidateGrid = CandidateGrid(),  # noqa: B008 (frozen dataclass)
                  rules: Feasibility | None = None,
                  options: CalibrationOptions = CalibrationOptions(),  # noqa: B008
                  avoid: Sequence[Placement] = ()) -> ViewSuggestions:
    """The ``n`` best next views for a person holding the target (module docstring). ``avoid``:
    placements whose views the detector refused; no candidate in their neighbourhood (not
    :func:`distinct` from one) is offered, as for a captured view (:func:`unseen`)."""
    width = size.width
    pred = ViewPredictor(Linearisation.of_refinement(res), size)
    rules = rules or default_feasibility(target, width, view_distances(target, res))
    placements = candidate_placements(pred.camera_sized, grid, target) + partial_placements(pred.camera_sized, target)
    cands = feasible_candidates(target, pred.camera_sized, placements, rules)
    assert res.x is not None
    R, t = res.view_poses_of(res.x)
    cands = unseen(cands, captured_placements(target, pred.camera_sized, R, t) + list(avoid), size)
    ranked = rank_candidates(pred, target, cands, n, options)
    return ViewSuggestions(pred.sigma_now(), pred.distance_now, ranked, len(cands), pred.camera_sized)
