"""Each view's camera pose (target -> camera) with the calibrated camera: the intrinsic refinement's
own pose of the view where it has one (:func:`refined_poses`), else from the circles
(:func:`~..initial.pose_with_camera`) or PnP on the undistorted checkerboard corners, polished on the
view's own edges (and corners) to the accuracy the hand-eye start needs."""

from __future__ import annotations

import cv2
import numpy as np

from ...detect import Detection
from ...geometry import DISTORTION_CHOICES, Camera, CircularPointError, Transform
from ...targets import Target
from ..intrinsic.initial import pose_with_camera
from ..intrinsic.options import CalibrationOptions, observations
from ..intrinsic.result import CalibrationResult, ViewReport
from ..solver.lm import levenberg_marquardt
from ..solver.observations import ViewData
from ..solver.problem import Problem


def camera_pose(det: Detection, target: Target, cam: Camera, origin: tuple[float, float]) -> Transform:
    """Target (local frame) -> camera for one view with the calibrated camera."""
    if det.edges:
        p = pose_with_camera(det, target, cam, origin)
        return Transform.from_rt(p.R, p.t)
    if det.corners is None or target.board is None:
        raise CircularPointError("no circles and no checkerboard corners")
    xy = cam.undistort_pixels(det.corners)
    obj = target.board.corner_points() - np.array(origin)
    ok = np.all(np.isfinite(xy), 1)
    if ok.sum() < 6:
        raise CircularPointError("fewer than 6 corners with a ray")
    found, rv, t = cv2.solvePnP(np.c_[obj[ok], np.zeros(ok.sum())].astype(np.float64), xy[ok].astype(np.float64),
                                np.eye(3), None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not found:
        raise CircularPointError("PnP on the checkerboard corners failed")
    return Transform.from_rotvec(np.ravel(rv), np.ravel(t))


def polished_pose(view: ViewData, C: Transform, cam: Camera, opt: CalibrationOptions, dof: int) -> Transform:
    """The view's pose refined on its edges (and corners) with the camera held fixed (the closed
    form poses are good to a few degrees only; the hand-eye start needs them to the edges'
    accuracy). A 5-dof (single ring) pose keeps a rotation vector without z component."""
    lens = DISTORTION_CHOICES[opt.distortion][0]
    D = np.asarray(cam.D, float).reshape(-1)
    intr0 = np.array([cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2], cam.K[0, 1], *D])
    if dof == 5:
        n = C.R[:, 2]
        axis = np.cross([0.0, 0.0, 1.0], n)
        s = float(np.linalg.norm(axis))
        rv = axis / s * np.arctan2(s, n[2]) if s > 1e-12 else np.zeros(3)
        p0 = np.r_[rv[:2], C.translation]
    else:
        p0 = np.r_[C.rotvec, C.translation]
    prob = Problem([view], dof, (), opt.edge_offsets and len(view.points) > 0, lens=lens)
    sol = levenberg_marquardt(prob, prob.pack(intr0, [p0], np.zeros(1)), intr0, 0.3, max_iter=30)
    p = prob.unpack(sol.x, intr0)[2][0]
    if dof == 5:
        return Transform.from_rotvec([p[0], p[1], 0.0], p[2:5])
    return Transform.from_rotvec(p[:3], p[3:6])


def refined_poses(cal: CalibrationResult) -> dict[int, Transform]:
    """The refinement's pose of each view it used (the view's index in the session -> target in
    its local frame -> camera): at the joint optimum, so the pose with the calibrated camera held
    fixed already. ``cal.poses`` lists them in the order of the used views; a 5-dof pose (single
    ring) is a rotation vector without z component and the translation. Empty if they do not match."""
    used = [k for k, v in enumerate(cal.views) if v.used]
    if not cal.refined or len(used) != len(cal.poses):
        return {}
    out = {}
    for k, p in zip(used, cal.poses, strict=True):
        p = np.asarray(p, float).reshape(-1)
        if len(p) == 5:
            out[k] = Transform.from_rotvec([p[0], p[1], 0.0], p[2:5])
        elif len(p) == 6:
            out[k] = Transform.from_rotvec(p[:3], p[3:6])
        else:
            return {}
    return out


def posed_views(dets: list[Detection], reports: list[ViewReport], target: Target, cam: Camera,
                options: CalibrationOptions, axisymmetric: bool, known: dict[int, Transform] | None = None,
                observed: dict[int, ViewData] | None = None) -> tuple[list[ViewData], list[Transform], list[int]]:
    """(observations, camera pose, index into the session) of every used view that can be posed
    with the calibrated camera; a view that cannot is marked unused in ``reports`` with the reason.
    ``known``: poses already at hand (:func:`refined_poses`), used as they are; ``observed``: views'
    observations already at hand (:func:`~..observations.observations` of the same detections)."""
    origin = target.local_origin
    views: list[ViewData] = []
    C: list[Transform] = []
    idx: list[int] = []
    known = known or {}
    for k, rep in enumerate(reports):
        if not rep.used:
            continue
        vd = observed[k] if observed and k in observed else observations(dets[k], target, origin, options)
        try:
            dof = 5 if axisymmetric else 6
            C.append(known[k] if k in known else
                     polished_pose(vd, camera_pose(dets[k], target, cam, origin), cam, options, dof))
        except (CircularPointError, np.linalg.LinAlgError, ValueError) as e:
            rep.used, rep.reason = False, f"pose with the calibrated camera: {e}"
            continue
        views.append(vd)
        idx.append(k)
    return views, C, idx
