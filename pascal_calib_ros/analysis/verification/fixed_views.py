"""Fresh views with the calibration held: every view's target pose (and edge offset) fitted with K
and D fixed, the first step of :mod:`.verify`.

Each usable detection is posed with the calibrated camera (circles: the closed form in the
camera's own rays; checkerboard only: PnP on undistorted corners), then all poses are refined
together on every edge point and corner with the intrinsics held (:class:`~..calibrate.refine.
Problem` with no free intrinsics: the views are independent, so this is one small fit per view).
A view whose edge RMS exceeds ``outlier_factor`` times the median is dropped with the reason (moved
during the exposure, a wrong detection), as the calibration itself does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...calibrate import (
    CalibrationOptions,
    PlanePose,
    Problem,
    ViewData,
    levenberg_marquardt,
    observations,
    pose_to_params,
)
from ...calibrate.handeye import camera_pose
from ...detect import Detection
from ...errors import PascalCalibError
from ...geometry import Camera, CircularPointError, Transform
from ...targets import Target

MIN_VIEWS = 3


class VerifyError(PascalCalibError):
    """The fresh views cannot test the calibration (too few usable views, another image size)."""


@dataclass
class FreshViews:
    """The fresh views' observations and their poses with the calibration held."""

    views: list[ViewData]
    poses: list[np.ndarray]  # per view: 6 (rvec, t) or 5 (single ring) parameters
    offsets: np.ndarray
    dof: int
    use_offsets: bool
    rms_fixed: float  # edge RMS (px; corner RMS for corner-only views) with the calibration held
    used: list[int]  # indices of the detections used
    reports: list[tuple[str, bool, str]] = field(default_factory=list)  # (name, used, reason) per detection
    origin: tuple[float, float] = (0.0, 0.0)

    @property
    def camera_poses(self) -> list[Transform]:
        """Target (refinement's local frame) -> camera per used view."""
        out = []
        for p in self.poses:
            rv = p[:3] if self.dof == 6 else np.r_[p[:2], 0.0]
            out.append(Transform.from_rotvec(rv, p[self.dof - 3:self.dof]))
        return out


def _fit(views: list[ViewData], poses: list[np.ndarray], cam: Camera, dof: int, use_offsets: bool
         ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, float]:
    """Poses and offsets with K, D held; per-view RMS and the overall RMS of the robust rows."""
    D = np.asarray(cam.D, float)
    intr0 = np.r_[cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2], cam.K[0, 1], D]
    prob = Problem(views, dof, (), use_offsets, lens=cam.lens)
    sol = levenberg_marquardt(prob, prob.pack(intr0, poses, np.zeros(len(views))), intr0, 0.3, max_iter=60)
    _, _, P, offsets = prob.unpack(sol.x, intr0)
    f = sol.fun
    per_view = np.array([float(np.sqrt(np.mean(f[r] ** 2))) if len(r) else 0.0 for r in prob.rows_of_view])
    return [p.copy() for p in P], offsets, per_view, float(np.sqrt(np.mean(f**2))) if len(f) else float("nan")


def fit_fresh_views(dets: list[Detection], target: Target, cam: Camera,
                    options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                    outlier_factor: float = 4.0) -> FreshViews:
    """Pose every usable detection with ``cam`` held (module docstring). Raises
    :class:`VerifyError` with fewer than :data:`MIN_VIEWS` usable views or another image size."""
    sizes = {(d.width, d.height) for d in dets if d.ok}
    if sizes and sizes != {(cam.width, cam.height)}:
        raise VerifyError(f"the views are {', '.join(f'{w}x{h}' for w, h in sorted(sizes))}, the calibration "
                          f"{cam.width}x{cam.height}: verify needs views of the calibrated camera mode")
    origin = target.local_origin
    dof = 6 if (len({c.center for c in target.circles}) > 1 or target.boards) else 5
    reports = [(d.name or f"view{k}", d.ok, d.reason) for k, d in enumerate(dets)]
    views, poses, used = [], [], []
    for k, d in enumerate(dets):
        if not d.ok:
            continue
        try:
            C = camera_pose(d, target, cam, origin)
        except (CircularPointError, np.linalg.LinAlgError, ValueError) as e:
            reports[k] = (reports[k][0], False, f"pose with the calibrated camera: {e}")
            continue
        views.append(observations(d, target, origin, options))
        poses.append(pose_to_params(PlanePose(C.R, C.translation), dof))
        used.append(k)
    if len(used) < MIN_VIEWS:
        raise VerifyError(f"{len(used)} usable view(s) of {len(dets)}; verify needs at least {MIN_VIEWS} views of the "
                          "target spread over the image (" + "; ".join(f"{n}: {r}" for n, ok, r in reports
                                                                       if not ok and r) + ")")
    use_offsets = options.edge_offsets and all(len(v.points) for v in views)
    poses, offsets, per_view, rms = _fit(views, poses, cam, dof, use_offsets)
    med = float(np.median(per_view))
    bad = [i for i, r in enumerate(per_view) if r > outlier_factor * max(med, 0.02)]
    if bad and len(used) - len(bad) >= MIN_VIEWS:
        for i in bad:
            k = used[i]
            reports[k] = (reports[k][0], False, f"outlier: RMS {per_view[i]:.3f} px with the calibration held is "
                                                f"{per_view[i] / max(med, 1e-9):.1f}x the median {med:.3f} px")
        keep = [i for i in range(len(used)) if i not in bad]
        views, used = [views[i] for i in keep], [used[i] for i in keep]
        poses, offsets, per_view, rms = _fit(views, [poses[i] for i in keep], cam, dof, use_offsets)
    return FreshViews(views=views, poses=poses, offsets=offsets, dof=dof, use_offsets=use_offsets, rms_fixed=rms,
                      used=used, reports=reports, origin=origin)
