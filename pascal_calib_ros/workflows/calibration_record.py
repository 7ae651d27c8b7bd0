"""The :class:`~..io.calibration_json.CalibrationRecord` of a calibration result: the camera, the
marginal covariance of the estimated intrinsics and the observed field, for ``calibration.json``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..analysis import Assessment
from ..calibrate import CalibrationResult, RigResult
from ..geometry import view_hulls
from ..io import CalibrationRecord


def intrinsic_covariance(res: CalibrationResult) -> tuple[tuple[str, ...], np.ndarray | None]:
    """(names, covariance) of the estimated intrinsics (fx fy cx cy [skew] and the estimated
    coefficients): the leading block of the refinement's sandwich covariance, which is the
    intrinsics' marginal covariance with every view's pose and edge offset estimated too. Without a
    refinement (zhang, --no-refine) the names of ``res.std`` and no covariance."""
    ref = res.refinement
    if ref is None or ref.covariance is None or ref.problem is None:
        return tuple(res.std), None
    prob = ref.problem
    names = tuple(prob.names[i] for i in prob.free)
    n = len(names)
    return names, np.asarray(ref.covariance[:n, :n], float).copy()


def record_of_result(res: CalibrationResult, camera_name: str = "camera") -> CalibrationRecord:
    """A calibration as a record: its camera, what it estimated and the covariance of that
    (:func:`intrinsic_covariance`), its fit."""
    names, cov = intrinsic_covariance(res)
    return CalibrationRecord(camera=res.camera(), camera_name=camera_name, distortion_choice=res.distortion_model,
                             parameters=names, covariance=cov, rms_px=float(res.rms), views_used=res.n_used)


def record_of_calibration(a: Assessment, camera_name: str = "camera", note: str = "") -> CalibrationRecord:
    """What ``calibration.json`` keeps of an assessed calibration (module docstring)."""
    res = a.result
    proj = a.projection_summary()
    hulls = view_hulls(res.feature_points()) if res.edge_points else []
    summary = {k: float(v) for k, v in proj.items()} if proj and all(np.isfinite(list(proj.values()))) else None
    return replace(record_of_result(res, camera_name), view_hulls=hulls, projection_uncertainty=summary, note=note)


def record_of_rig_camera(rig: RigResult, c: int, a: Assessment, camera_name: str) -> CalibrationRecord:
    """The record of camera ``c`` of a jointly calibrated rig (``a``: its assessment,
    :func:`~..analysis.rig.assess_rig`): its intrinsics' covariance is their block of the joint
    sandwich covariance, i.e. their marginal with the rig's transforms and every shot's pose
    estimated too."""
    rec = record_of_calibration(a, camera_name, note=f"camera {rig.names[c]!r} of a rig of {len(rig.names)} "
                                                     "calibrated jointly")
    sub, lo, hi = rig.problem.subs[c], int(rig.problem.intr_start[c]), int(rig.problem.intr_start[c + 1])
    cov = None if rig.covariance is None else np.asarray(rig.covariance[lo:hi, lo:hi], float).copy()
    return replace(rec, parameters=tuple(sub.names[i] for i in sub.free), covariance=cov)
