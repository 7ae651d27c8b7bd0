"""What a rig's joint calibration is worth, per camera: mrcal's projection uncertainty through the
whole rig's covariance (the camera's intrinsics, its pose in the rig and the shots it saw), and
each camera's assessment (:mod:`.assessment`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ...calibrate import RigResult
from ...geometry import Camera
from .assessment import Assessment, model_bias_of
from .uncertainty import ProjectionUncertainty, projection_uncertainty


def rig_camera_projection(rig: RigResult, c: int, distance: float | None = None) -> ProjectionUncertainty | None:
    """Camera ``c``'s projection uncertainty at ``distance`` metres (default: the median distance to
    the target over its views); None without a covariance."""
    if rig.covariance is None:
        return None
    prob, intr0, cam = rig.problem, rig.intr0, rig.cameras[c].camera()

    def camera_of(x: np.ndarray) -> Camera:
        i = prob.unpack(x, intr0)[0][c]
        K = np.array([[i[0], i[4], i[2]], [0, i[1], i[3]], [0, 0, 1.0]])
        return Camera(K, i[5:].copy(), cam.width, cam.height, cam.model)

    def view_poses_of(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _, ext, shots, _ = prob.unpack(x, intr0)
        rv, t, _, _ = prob.view_poses(c, ext, shots)
        return Rotation.from_rotvec(rv).as_matrix().reshape(-1, 3, 3), t

    d = float(np.median(np.linalg.norm(view_poses_of(rig.x)[1], axis=1))) if distance is None else distance
    out = projection_uncertainty(camera_of, view_poses_of, rig.x, rig.covariance, cam.size, d)
    out.default_distance = distance is None
    return out


def assess_rig(rig: RigResult, distance: float | None = None) -> list[Assessment]:
    """Every camera of the rig assessed: its projection uncertainty through the rig and its
    model-bias verdict."""
    out = []
    for c, res in enumerate(rig.cameras):
        bias = model_bias_of(res) if res.edge_points else None
        out.append(Assessment(res, rig_camera_projection(rig, c, distance), bias))
    return out
