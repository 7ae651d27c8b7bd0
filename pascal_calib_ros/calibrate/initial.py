"""Closed-form initialisation: circular points per view -> w -> K, then each view's pose.

Methods (PAPER.md): ``ring`` (concentric pair, closed form), ``pt2`` / ``pt1`` (Pascal hexagon
with the ring's vanishing line, Newton), ``huang`` (two separated coplanar circles).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..detect.rings import Detection
from ..geometry.camera import rodrigues, rotation_to_rvec
from ..geometry.circular import (
    PT1_STARTS,
    CircularPointError,
    centre_image_from_ring,
    circular_point_pt2,
    circular_points_from_ring,
    circular_points_huang,
    circular_points_pt1,
    vanishing_line_from_centre,
    vanishing_line_huang,
)
from ..geometry.conic import Ellipse, normalize_conic
from ..geometry.iac import IacSolution, iac_from_circular_points
from ..targets import Target

CIRCLE_METHODS = ("ring", "pt2", "pt1", "huang")


def pascal_points(C: np.ndarray, n: int = 5, phase: float = 0.3) -> np.ndarray:
    """n points on the conic, evenly spread (the paper's "average" layout)."""
    return Ellipse.from_conic(C).sample(n, phase)


def circular_point_of_view(det: Detection, target: Target, method: str) -> np.ndarray:
    """i' of one view by ``method``. Raises :class:`CircularPointError`."""
    if method in ("ring", "pt2", "pt1"):
        e_out, e_in = det.edge(0), det.edge(1)
        if not target.rings or e_out is None or e_in is None:
            raise CircularPointError(f"method {method!r} needs the ring's two edges")
        if method == "ring":
            return circular_points_from_ring(e_out.conic, e_in.conic)[0]
        c = centre_image_from_ring(e_out.conic, e_in.conic)
        line = vanishing_line_from_centre(e_out.conic, c)
        pts = pascal_points(e_out.conic)
        if method == "pt2":
            res = circular_point_pt2(pts, line)
        else:
            for start in PT1_STARTS:  # pt1 may collapse to i' = j': try further starts
                res = circular_points_pt1(pts, line, start)
                if res.converged:
                    break
        if not res.converged:
            raise CircularPointError(f"{method} Newton did not converge to a circular point")
        return res.point
    if method == "huang":
        edges = [e for e in det.edges if target.circles[e.circle].dark_inside]
        if len(edges) < 2:
            raise CircularPointError("huang needs two separated circles (ring outer edge + disc)")
        return circular_points_huang(edges[0].conic, edges[1].conic)[0]
    raise ValueError(f"unknown method {method!r}; choose from {', '.join(CIRCLE_METHODS)}")


def vanishing_line_of_view(det: Detection, target: Target) -> np.ndarray:
    e_out, e_in = det.edge(0), det.edge(1)
    if target.rings and e_out is not None and e_in is not None:
        return vanishing_line_from_centre(e_out.conic, centre_image_from_ring(e_out.conic, e_in.conic))
    edges = [e for e in det.edges if target.circles[e.circle].dark_inside]
    if len(edges) >= 2:
        return vanishing_line_huang(edges[0].conic, edges[1].conic)
    raise CircularPointError("no vanishing line: the view needs the ring or two circles")


def intrinsics_closed_form(dets: list[Detection], target: Target, method: str, zero_skew: bool = False
                           ) -> tuple[IacSolution, list[int], dict[int, str]]:
    """K from the circular points of the usable views. Returns the solution, the indices of the
    views used and a reason for every view that could not give a circular point."""
    pts, used, failed = [], [], {}
    for k, d in enumerate(dets):
        try:
            pts.append(circular_point_of_view(d, target, method))
            used.append(k)
        except (CircularPointError, np.linalg.LinAlgError) as exc:
            failed[k] = str(exc)
    w, h = dets[0].width, dets[0].height
    return iac_from_circular_points(pts, w, h, zero_skew), used, failed


@dataclass(frozen=True)
class PlanePose:
    R: np.ndarray  # target (local frame, origin at the first circle's centre) -> camera
    t: np.ndarray


def pose_from_view(det: Detection, target: Target, K: np.ndarray, origin: tuple[float, float]) -> PlanePose:
    """Pose of the target plane from the ring (or two circles) and K.

    Normal n ~ K^T l (l the vanishing line), centre X0 = lambda K^-1 c with lambda from the
    circle's radius: for H = K [r1 r2 X0], H^T C H ~ diag(1, 1, -R^2). The rotation about n comes
    from the other features (disc centre, checkerboard corners) when the target has them."""
    line = vanishing_line_of_view(det, target)
    circle_idx = 0
    e0 = det.edge(circle_idx)
    if e0 is None:
        e0 = det.edges[0]
        circle_idx = e0.circle
    circ = target.circles[circle_idx]
    C = normalize_conic(e0.conic)
    if target.rings and det.edge(1) is not None:
        c = centre_image_from_ring(C, det.edge(1).conic)  # type: ignore[union-attr]
    else:
        # centre image = pole of the vanishing line w.r.t. the conic
        c = np.linalg.solve(C, line)
        c = c / c[2]
    d = np.linalg.solve(K, c)
    n = K.T @ line
    n = n / np.linalg.norm(n)
    if n @ d < 0:
        n = -n
    # rotation taking z to n about an axis in the camera's x-y plane
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s = np.linalg.norm(axis)
    ang = np.arctan2(s, n @ z)
    R = rodrigues(axis / s * ang) if s > 1e-12 else np.eye(3)
    r1, r2 = R[:, 0], R[:, 1]
    a11 = (K @ r1) @ C @ (K @ r1)
    a22 = (K @ r2) @ C @ (K @ r2)
    ccc = c @ C @ c
    if ccc >= 0 or a11 + a22 <= 0:
        raise CircularPointError("circle centre not inside its image conic")
    lam = circ.radius * np.sqrt(-(a11 + a22) / 2 / ccc)
    X0 = lam * d
    # position of this circle's centre in the local frame
    local_c = np.array([circ.center[0] - origin[0], circ.center[1] - origin[1], 0.0])
    R = _in_plane_rotation(det, target, K, R, X0, circ.center, origin)
    t = X0 - R @ local_c
    return PlanePose(R, t)


def _in_plane_rotation(det: Detection, target: Target, K: np.ndarray, R: np.ndarray, X0: np.ndarray,
                       ref_centre: tuple[float, float], origin: tuple[float, float]) -> np.ndarray:
    """Rotate R about its z axis so that the other features land where the target has them."""
    obs: list[np.ndarray] = []
    ref: list[np.ndarray] = []
    H = K @ np.column_stack([R[:, 0], R[:, 1], X0])  # local plane (centred on ref circle) -> image
    for e in det.edges:
        circ = target.circles[e.circle]
        if np.hypot(circ.center[0] - ref_centre[0], circ.center[1] - ref_centre[1]) < 1e-9:
            continue
        M = H.T @ normalize_conic(e.conic) @ H
        try:
            ctr = -np.linalg.solve(M[:2, :2], M[:2, 2])
        except np.linalg.LinAlgError:
            continue
        obs.append(ctr)
        ref.append(np.array(circ.center) - np.array(ref_centre))
    if det.corners is not None and target.checkerboard is not None:
        Hi = np.linalg.inv(H)
        q = np.concatenate([det.corners, np.ones((len(det.corners), 1))], 1) @ Hi.T
        obs.extend(q[:, :2] / q[:, 2:3])
        ref.extend(target.checkerboard.corner_points() - np.array(ref_centre))
    if not obs:
        return R
    ob, P = np.array(obs), np.array(ref)
    ang = np.arctan2(np.sum(P[:, 0] * ob[:, 1] - P[:, 1] * ob[:, 0]), np.sum(P[:, 0] * ob[:, 0] + P[:, 1] * ob[:, 1]))
    # plane coords o = Rz(ang) p: the target's x axis appears rotated by ang in the plane basis
    return R @ rodrigues(np.array([0.0, 0.0, ang]))


def pose_to_params(pose: PlanePose, dof: int) -> np.ndarray:
    """6-dof: rvec, t. 5-dof (single ring, rotation about its axis unobservable): the rotation
    vector's x, y (z fixed at 0, i.e. the rotation maps z to the normal about an in-plane axis), t."""
    if dof == 6:
        return np.concatenate([rotation_to_rvec(pose.R), pose.t])
    n = pose.R[:, 2]
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s = np.linalg.norm(axis)
    rv = axis / s * np.arctan2(s, n @ z) if s > 1e-12 else np.zeros(3)
    return np.concatenate([rv[:2], pose.t])
