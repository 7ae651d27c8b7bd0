"""Closed-form initialisation: circular points per view -> w -> K, then each view's pose.

Methods (PAPER.md): ``ring`` (concentric pair, closed form), ``pt2`` / ``pt1`` (Pascal hexagon
with the ring's vanishing line, Newton), ``huang`` (two separated coplanar circles).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...detect import Detection
from ...geometry import (
    PT1_STARTS,
    Camera,
    CircularPointError,
    Ellipse,
    IacSolution,
    ImageSize,
    IndefiniteOmegaError,
    centre_image_from_ring,
    circular_point_pt2,
    circular_points_from_ring,
    circular_points_huang,
    circular_points_pt1,
    ellipses_from_conics,
    fit_conics_algebraic,
    fit_homography,
    iac_focal_only,
    iac_from_circular_points,
    normalize_conic,
    rodrigues,
    rotation_to_rvec,
    vanishing_line_from_centre,
    vanishing_line_huang,
)
from ...targets import Target

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


def _grid_elements(det: Detection, target: Target) -> list[tuple[np.ndarray, np.ndarray | None, np.ndarray]]:
    """(outer conic, inner conic or None, element centre on the sheet) of each measured element."""
    by_idx = {e.circle: e for e in det.edges}
    out = []
    for e in det.edges:
        c = target.circles[e.circle]
        if not c.dark_inside:
            continue
        inner = by_idx.get(e.circle + 1)
        inner_ok = inner is not None and not target.circles[e.circle + 1].dark_inside and \
            target.circles[e.circle + 1].center == c.center
        out.append((e.conic, inner.conic if inner_ok and inner is not None else None, np.array(c.center)))
    return out


def circular_points_of_grid_view(det: Detection, target: Target, method: str, max_points: int = 12
                                 ) -> list[np.ndarray]:
    """Several i' of one grid view: one per ring element (ring, pt2, pt1), or one per pair of
    far-apart elements (huang), spread over the board."""
    elems = _grid_elements(det, target)
    if len(elems) < 2:
        raise CircularPointError("fewer than two grid elements measured")
    centres = np.array([c for _, _, c in elems])
    pts: list[np.ndarray] = []
    if method in ("ring", "pt2", "pt1"):
        rings = [k for k, (_, inner, _) in enumerate(elems) if inner is not None]
        if not rings:
            raise CircularPointError(f"method {method!r} needs ring elements")
        pick = [rings[round(x)] for x in np.linspace(0, len(rings) - 1, min(max_points, len(rings)))]
        for k in pick:
            outer, inner, _ = elems[k]
            assert inner is not None
            if method == "ring":
                pts.append(circular_points_from_ring(outer, inner)[0])
                continue
            line = vanishing_line_from_centre(outer, centre_image_from_ring(outer, inner))
            five = pascal_points(outer)
            res = circular_point_pt2(five, line) if method == "pt2" else circular_points_pt1(five, line)
            if res.converged:
                pts.append(res.point)
    elif method == "huang":
        order = np.argsort(centres[:, 0] + 1e-3 * centres[:, 1])
        half = max(1, len(order) // 2)
        for a, b in zip(order[:half][:max_points], order[::-1][:half][:max_points], strict=False):
            if a == b:
                continue
            try:
                pts.append(circular_points_huang(elems[a][0], elems[b][0])[0])
            except CircularPointError:
                continue
    else:
        raise ValueError(f"unknown method {method!r}")
    if not pts:
        raise CircularPointError(f"no circular point from the grid by {method}")
    return pts


def intrinsics_closed_form(dets: list[Detection], target: Target, method: str, zero_skew: bool = False,
                           focal_only: bool = False) -> tuple[IacSolution, list[int], dict[int, str]]:
    """K from the circular points of the usable views. Returns the solution, the indices of the
    views used and a reason for every view that could not give a circular point. ``focal_only``:
    when the full w is not positive definite, f alone with the principal point at the image centre
    (:func:`..geometry.iac.iac_focal_only`)."""
    pts, used, failed = [], [], {}
    for k, d in enumerate(dets):
        try:
            if target.grids:
                pts.extend(circular_points_of_grid_view(d, target, method))
            else:
                pts.append(circular_point_of_view(d, target, method))
            used.append(k)
        except (CircularPointError, np.linalg.LinAlgError) as exc:
            failed[k] = str(exc)
    w, h = dets[0].width, dets[0].height
    try:
        return iac_from_circular_points(pts, ImageSize(w, h), zero_skew), used, failed
    except IndefiniteOmegaError:
        if not focal_only:
            raise
        return iac_focal_only(pts, ImageSize(w, h)), used, failed


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
    if det.corners is not None and target.board is not None:
        Hi = np.linalg.inv(H)
        q = np.concatenate([det.corners, np.ones((len(det.corners), 1))], 1) @ Hi.T
        obs.extend(q[:, :2] / q[:, 2:3])
        ref.extend(target.board.corner_points() - np.array(ref_centre))
    if not obs:
        return R
    ob, P = np.array(obs), np.array(ref)
    ang = np.arctan2(np.sum(P[:, 0] * ob[:, 1] - P[:, 1] * ob[:, 0]), np.sum(P[:, 0] * ob[:, 0] + P[:, 1] * ob[:, 1]))
    # plane coords o = Rz(ang) p: the target's x axis appears rotated by ang in the plane basis
    return R @ rodrigues(np.array([0.0, 0.0, ang]))


def pose_from_circles(det: Detection, target: Target, K: np.ndarray, origin: tuple[float, float]) -> PlanePose:
    """Pose of a board of many circles from K: the plane normal from the vanishing line
    (n ~ K^T l), every circle's conic back-projected onto the plane at unit distance
    (H0 = K [r1 r2 n], M = H0^T C H0) gives its exact centre, and a 2-D similarity (Umeyama)
    between those centres and the sheet's gives the rotation about n and the distance (1/scale).
    No fitted-ellipse centre is used: they are biased under perspective."""
    elems = _grid_elements(det, target) if target.grids else [
        (e.conic, None, np.array(target.circles[e.circle].center)) for e in det.edges
        if target.circles[e.circle].dark_inside]
    if len(elems) < 3:
        raise CircularPointError("fewer than three circles for a board pose")
    lines = []
    for outer, inner, _ in elems:
        if inner is not None:
            lines.append(vanishing_line_from_centre(outer, centre_image_from_ring(outer, inner)))
    if not lines:
        centres_img = np.array([Ellipse.from_conic(o).cx for o, _, _ in elems])
        a, b = int(np.argmin(centres_img)), int(np.argmax(centres_img))
        lines.append(vanishing_line_huang(elems[a][0], elems[b][0]))
    ref = lines[0]
    line = np.mean([ln if ln @ ref >= 0 else -ln for ln in lines], axis=0)
    n = K.T @ line
    n = n / np.linalg.norm(n)
    e0 = Ellipse.from_conic(elems[0][0])
    c0 = np.linalg.solve(K, np.array([e0.cx, e0.cy, 1.0]))
    if n @ c0 < 0:
        n = -n
    r1 = np.cross([0.0, 1.0, 0.0], n)
    r1 /= np.linalg.norm(r1)
    r2 = np.cross(n, r1)
    H0 = K @ np.column_stack([r1, r2, n])
    obs, ref_pts = [], []
    for outer, _, centre in elems:
        M = H0.T @ normalize_conic(outer) @ H0
        try:
            obs.append(-np.linalg.solve(M[:2, :2], M[:2, 2]))
        except np.linalg.LinAlgError:
            continue
        ref_pts.append(centre - np.array(origin))
    ob, P = np.array(obs), np.array(ref_pts)
    mo, mp = ob.mean(0), P.mean(0)
    U, S, Vt = np.linalg.svd((ob - mo).T @ (P - mp))
    if np.linalg.det(U @ Vt) < 0:
        raise CircularPointError("the circles' layout is mirrored against the target: wrong target file?")
    Rth = U @ Vt
    s = S.sum() / np.sum((P - mp) ** 2)
    d = 1.0 / s
    t_m = d * (mo - s * Rth @ mp)
    R = np.column_stack([r1, r2, n]) @ np.block([[Rth, np.zeros((2, 1))], [np.zeros((1, 2)), np.ones((1, 1))]])
    t = np.column_stack([r1, r2]) @ t_m + d * n
    return PlanePose(R, t)


def grid_homography_init(dets: list[Detection], target: Target, origin: tuple[float, float], zero_skew: bool
                         ) -> tuple[IacSolution, list[PlanePose | None]]:
    """Approximate start for grid boards (method ``grid``): a homography per view from the
    element centres (fitted-ellipse centres of the plumb-line corrected edges: biased by up to a
    pixel under perspective, which is fine for a start and never used afterwards), Zhang's
    constraints i' = h1 + i h2 on w, K by Cholesky, poses from H and K (Zhang 2000, sec. 3.1).
    The refinement then fits every edge point to its projected circle."""
    Hs: list[np.ndarray | None] = []
    pts = []
    for d in dets:
        outer = [e for e in d.edges if target.circles[e.circle].dark_inside]
        par, real = ellipses_from_conics(np.array([e.conic for e in outer]))
        src = [[target.circles[e.circle].center[0] - origin[0], target.circles[e.circle].center[1] - origin[1]]
               for e, ok in zip(outer, real, strict=True) if ok]
        dst = [p[:2] for p, ok in zip(par, real, strict=True) if ok]
        if len(src) < 6:
            Hs.append(None)
            continue
        H = fit_homography(np.array(src), np.array(dst))
        Hs.append(H)
        pts.append(H[:, 0] + 1j * H[:, 1])
    sol = iac_from_circular_points(pts, dets[0].size, zero_skew)
    Ki = np.linalg.inv(sol.K)
    poses: list[PlanePose | None] = []
    for Hv in Hs:
        if Hv is None:
            poses.append(None)
            continue
        H = Hv
        lam = 1.0 / np.linalg.norm(Ki @ H[:, 0])
        if (Ki @ H[:, 2])[2] * lam < 0:
            lam = -lam
        r1, r2, t = lam * Ki @ H[:, 0], lam * Ki @ H[:, 1], lam * Ki @ H[:, 2]
        U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
        R = U @ Vt
        if np.linalg.det(R) < 0:
            R = U @ np.diag([1, 1, -1]) @ Vt
        poses.append(PlanePose(R, t))
    return sol, poses


def pose_with_camera(det: Detection, target: Target, camera: Camera, origin: tuple[float, float]) -> PlanePose:
    """Pose of a view from a calibrated camera of any lens model, wherever the target is in the
    field (fisheye rays beyond 90 degrees included): the edges' rays are turned by a rotation Q
    that puts their mean on the optical axis and drawn in a distortion-free pinhole camera there
    (focal fx), where the circles are exact conics again; the pose found there by
    :func:`pose_from_circles` (grids) or :func:`pose_from_view` is turned back (R = Q^T R_v,
    t = Q^T t_v)."""
    # one unprojection of every edge point (the model's range is found once, not per edge), split per edge
    allr = camera.unproject(np.concatenate([e.points for e in det.edges])) if det.edges else np.zeros((0, 3))
    rays = np.split(allr, np.cumsum([len(e.points) for e in det.edges])[:-1]) if det.edges else []
    allr = allr[np.all(np.isfinite(allr), 1)]
    if len(allr) < 10:
        raise CircularPointError("no edge point has a ray under the calibrated camera")
    m = allr.mean(0)
    m /= np.linalg.norm(m)
    axis = np.cross(m, [0.0, 0.0, 1.0])
    s_ = float(np.linalg.norm(axis))
    Q = rodrigues(axis / s_ * np.arctan2(s_, float(m[2]))) if s_ > 1e-12 else np.eye(3)
    f = float(camera.K[0, 0])
    Kv = np.array([[f, 0.0, 0.0], [0.0, f, 0.0], [0.0, 0.0, 1.0]])

    def virtual(r: np.ndarray) -> np.ndarray:
        v = r @ Q.T
        ok = np.all(np.isfinite(v), 1) & (v[:, 2] > 0.1)
        return (f * v[ok, :2] / v[ok, 2:3]) if ok.any() else np.zeros((0, 2))

    pts = [virtual(r) for r in rays]
    keep = [k for k, p in enumerate(pts) if len(p) >= 12]
    if not keep:
        raise CircularPointError("no edge left in the virtual camera")
    owner = np.repeat(np.arange(len(keep)), [len(pts[k]) for k in keep])
    conics, ok = fit_conics_algebraic(np.concatenate([pts[k] for k in keep]), owner, len(keep))
    edges = [replace(det.edges[k], points=pts[k], conic=C) for k, C, g in zip(keep, conics, ok, strict=True) if g]
    corners = None
    if det.corners is not None:
        c = virtual(camera.unproject(det.corners))
        corners = c if len(c) == len(det.corners) else None
    vdet = replace(det, edges=edges, corners=corners)
    pose = pose_from_circles(vdet, target, Kv, origin) if target.grids else pose_from_view(vdet, target, Kv, origin)
    return PlanePose(Q.T @ pose.R, Q.T @ pose.t)


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
