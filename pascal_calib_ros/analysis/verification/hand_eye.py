"""Does a hand-eye result still hold? X re-estimated on fresh views and robot poses, tested
against its stored sigma (:mod:`.verify` for the intrinsics).

With the camera's intrinsics held at the calibration under test, the fresh views' camera poses
(:mod:`.verify_views`) and the robot's reported poses give the chain Y = M_i X C_i again. The
target's pose Y is estimated anew (the target may have been moved since the calibration), X is
started at the stored value and both are refined with the robot chain as a measurement, exactly
as the hand-eye calibration does (:func:`~..calibrate.handeye.chain_refinement.refine_chain`: the arm's random
error estimated from the data, the edges' robust loss, the arm's systematic error as a stated
prior). A symmetric target's views are labelled so that M_i X C_i agree across the views.

The disagreement dX = X_fresh X_stored^-1 (translation in mm and small rotation in degrees,
about the parent frame's axes, as HAND_EYE.yaml's sigmas) is tested per axis against
sigma^2 = sigma_stored^2 + sigma_fresh^2: both without the held intrinsics' share, since an error of
the intrinsics moves the stored and the fresh X alike (a principal point error is a constant
camera rotation dc / f that X absorbs in both; HAND_EYE.yaml keeps that share apart,
``*_std_intrinsics_*``); the fresh sigma is the refinement's covariance and the arm prior's share.
chi^2 = sum z^2 over the six axes, 6 degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from ...calibrate import CalibrationOptions, CalibrationResult
from ...calibrate.handeye import (
    ChainStart,
    HandEyeOptions,
    chain_pose,
    complete_ring_poses,
    refine_chain,
    relabelled,
    target_symmetries,
)
from ...geometry import Camera, Transform
from ...modes import HandEyeMode
from ...targets import Target
from .fixed_views import FreshViews, VerifyError


@dataclass(frozen=True)
class HandEyeReference:
    """The hand-eye result under test (HAND_EYE.yaml)."""

    mode: HandEyeMode
    X: Transform
    translation_std_mm: np.ndarray
    rotation_std_deg: np.ndarray
    parent_frame: str = ""
    child_frame: str = ""
    arm_accuracy_mm: float = 0.2  # the arm prior of the fresh estimate (HandEyeOptions)
    arm_accuracy_length: float = 0.3
    # of the stored sigmas, the held intrinsics' share (HAND_EYE.yaml *_std_intrinsics_*; zero if absent)
    intrinsics_share_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    intrinsics_share_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def comparable_std(self) -> tuple[np.ndarray, np.ndarray]:
        """The stored sigmas without the intrinsics' share (mm, deg per axis): what of the stored X's error a
        fresh estimate with the same intrinsics does not share."""
        t = np.sqrt(np.maximum(np.asarray(self.translation_std_mm) ** 2 - np.asarray(self.intrinsics_share_mm) ** 2, 0))
        r = np.sqrt(np.maximum(np.asarray(self.rotation_std_deg) ** 2 - np.asarray(self.intrinsics_share_deg) ** 2, 0))
        return t, r


@dataclass(frozen=True)
class HandEyeCheck:
    """X from the fresh views against the stored X (module docstring)."""

    X_fresh: Transform
    delta_mm: np.ndarray  # (3,) parent axes
    delta_deg: np.ndarray  # (3,) small rotation about the parent axes
    sigma_mm: np.ndarray  # (3,) sqrt(stored^2 + fresh^2)
    sigma_deg: np.ndarray
    sigma_fresh_mm: np.ndarray
    sigma_fresh_deg: np.ndarray
    chi2: float
    p_value: float
    changed: bool
    robot_error_mm: float  # the arm's random error the fresh data imply
    robot_error_deg: float

    @property
    def z(self) -> np.ndarray:
        """(6,): translation x y z, rotation x y z."""
        return np.r_[self.delta_mm / self.sigma_mm, self.delta_deg / self.sigma_deg]

    @property
    def translation_mm(self) -> float:
        return float(np.linalg.norm(self.delta_mm))

    @property
    def rotation_deg(self) -> float:
        return float(np.linalg.norm(self.delta_deg))


def _labelled(fv: FreshViews, C: list[Transform], M: list[Transform], X: Transform, target: Target
              ) -> tuple[list, list[Transform]]:
    """Views and camera poses relabelled by the target's symmetries so that M_i X C_i agree with
    view 0's."""
    syms = target_symmetries(target, fv.origin)
    views = list(fv.views)
    if len(syms) < 2:
        return views, C
    Y0 = M[0] @ X @ C[0]
    for i in range(1, len(C)):
        errs = [(Y0.inverse() @ M[i] @ X @ C[i] @ S).angle_deg() for S in syms]
        best = syms[int(np.argmin(errs))]
        if best.angle_deg() > 1.0:
            C[i] = C[i] @ best
            views[i] = relabelled(views[i], best)
    return views, C


def _mean_target(M: list[Transform], X: Transform, C: list[Transform]) -> Transform:
    Ys = [m @ X @ c for m, c in zip(M, C, strict=True)]
    rot = Rotation.concatenate([y.rotation for y in Ys]).mean()
    return Transform(rot, np.mean([y.translation for y in Ys], axis=0))


def check_hand_eye(fv: FreshViews, robot_poses: list[Transform], cam: Camera, choice: str, ref: HandEyeReference,
                   target: Target, level: float) -> HandEyeCheck:
    """Re-estimate X on the fresh views (``robot_poses``: T_base_tool per used view, in
    ``fv.used`` order) with ``cam`` held, and test it (module docstring); ``level``: the p-value
    below which X has changed."""
    if len(robot_poses) != len(fv.views):
        raise VerifyError(f"{len(robot_poses)} robot poses for {len(fv.views)} views")
    M = [chain_pose(G, ref.mode) for G in robot_poses]
    C = fv.camera_poses
    axisymmetric = fv.dof == 5
    views, C = (list(fv.views), C) if axisymmetric else _labelled(fv, C, M, ref.X, target)
    Y0 = _mean_target(M, ref.X, C)
    if axisymmetric:
        C = complete_ring_poses(M, ref.X, Y0, C)
    opt = CalibrationOptions(distortion=choice, zero_skew=cam.K[0, 1] == 0.0, edge_offsets=fv.use_offsets)
    he = HandEyeOptions(ref.mode, jackknife_groups=0, arm_accuracy_mm=ref.arm_accuracy_mm,
                        arm_accuracy_length=ref.arm_accuracy_length)
    cal = CalibrationResult(K=cam.K, D=np.asarray(cam.D, float), width=cam.width, height=cam.height, method="verify",
                            rms=fv.rms_fixed, std={}, degeneracy_ratio=float("nan"), views=[])
    sol = refine_chain(views, ChainStart(ref.X, Y0, C, M, cal), opt, he, target, fv.origin)
    X, err_mm, err_deg = sol.X, sol.robot_error_mm, sol.robot_error_deg
    s_f_t = np.sqrt(sol.covariance.x_mm**2 + sol.arm_share.x_mm**2)
    s_f_r = np.sqrt(sol.covariance.x_deg**2 + sol.arm_share.x_deg**2)
    d_mm = 1000 * (X.translation - ref.X.translation)
    d_deg = np.degrees((X.rotation * ref.X.rotation.inv()).as_rotvec())
    st_t, st_r = ref.comparable_std
    s_t = np.sqrt(s_f_t**2 + st_t**2)
    s_r = np.sqrt(s_f_r**2 + st_r**2)
    stat = float(np.sum((d_mm / s_t) ** 2) + np.sum((d_deg / s_r) ** 2))
    p = float(chi2.sf(stat, 6))
    return HandEyeCheck(X_fresh=X, delta_mm=d_mm, delta_deg=d_deg, sigma_mm=s_t, sigma_deg=s_r, sigma_fresh_mm=s_f_t,
                        sigma_fresh_deg=s_f_r, chi2=stat, p_value=p, changed=p < level, robot_error_mm=float(err_mm),
                        robot_error_deg=float(err_deg))
