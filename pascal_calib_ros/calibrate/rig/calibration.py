"""Joint calibration of a camera rig (a stereo pair, or N cameras) from the detections of shots.

``dets[c][s]`` is camera c's detection of shot s (a rejected detection where the camera did not
see the target whole, or has no image of the shot). Steps:

1. each camera is calibrated on its own (:func:`~.pipeline.calibrate`: closed form, refinement,
   outlier views, every lens model), and each of its used views posed with that camera;
2. connectivity, a consistent labelling of symmetric targets between the cameras, and each
   camera's extrinsic from the median of its per-shot relative poses (:mod:`.rig_start`);
3. one target pose per shot, from the first camera that saw it;
4. ONE joint refinement over every camera's edges (and corners) (:class:`~.rig_problem.RigProblem`
   with :func:`~.refine.levenberg_marquardt`): every camera's intrinsics and lens model, every
   camera's extrinsic, every shot's pose, every view's edge offset. A shot that only one camera
   saw whole serves that camera's intrinsics. A view whose edge RMS in the joint fit exceeds
   ``outlier_factor`` times the median is left out with its reason (the target moved between the
   exposures of unsynchronised cameras) and the fit repeated;
5. the covariance as for one camera (:mod:`.uncertainty`): the sandwich A^-1 B A^-1 with each
   camera's views as groups of their own noise s_g^2 and the camera's correlation factor kappa
   of its edge (and corner) rows; sigma of each extrinsic as small rotations about the camera's
   axes (deg) and translations (mm); each camera's projection uncertainty through the rig.

A single ring is refused: its rotation about its own axis is seen in no view, so a shot's two
views do not give a relative pose to start from.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...detect import Detection
from ...geometry import DISTORTION_CHOICES, CircularPointError, Transform, left_jacobian, skew
from ...targets import Target
from ..handeye.labelling import relabelled, target_symmetries
from ..handeye.view_poses import camera_pose, polished_pose, refined_poses
from ..intrinsic.options import CalibrationOptions, observations
from ..intrinsic.pipeline import calibrate
from ..intrinsic.result import CalibrationError, CalibrationResult, ViewReport
from ..solver.covariance import row_variances, sandwich_covariance
from ..solver.lm import LMResult, levenberg_marquardt
from ..solver.observations import ViewData
from ..solver.problem import Problem
from .problem import RigProblem
from .start import LabelMoves, RigStart, check_connected, rig_start

LOSS_SCALE = 0.3  # px, the soft-L1 scale of refine.refine
Key = tuple[int, int]  # (camera, shot) of a view
Sigmas = tuple[np.ndarray, np.ndarray]  # per-axis (deg (3,), mm (3,))


class RigError(CalibrationError):
    """The rig cannot be calibrated; the message says why and what to do."""


@dataclass(frozen=True)
class RigOptions:
    calibration: CalibrationOptions = field(default_factory=CalibrationOptions)
    # a view whose relative pose is further from the consensus than these is left out
    label_tolerance_deg: float = 2.0
    label_tolerance_rel: float = 0.01  # of the target's distance (at least 3 mm)
    outlier_factor: float = 4.0  # a view whose joint-fit RMS exceeds this times the median is left out
    relabel: bool = True  # False: views taken as labelled and all kept (comparison only)
    max_iter: int = 100
    # edge points per view in the joint fit (each camera's own calibration, only its start, keeps the
    # calibration options' budget): on 800x600 ring grids 3000 (about 20 per ring edge) against 700 gives
    # sigmas about 25 % smaller for about 15 % more time; more points change nothing further
    points_per_view: int = 3000


@dataclass
class RigResult:
    """A calibrated rig. ``extrinsics[c]`` maps camera 0's frame into camera c's (X_c = R X_0 + t,
    metres; a stereo pair's R, T); its sigma as small rotations about camera c's axes (deg) and
    translations (mm). ``pose_sigma[c]``: the same for camera c's pose in camera 0's frame
    (:meth:`pose_in_reference`), about camera 0's axes."""

    names: list[str]
    cameras: list[CalibrationResult]  # the joint estimate, per camera
    own: list[CalibrationResult]  # each camera calibrated on its own (the start)
    extrinsics: list[Transform]
    extrinsic_sigma: list[Sigmas]  # (deg (3,), mm (3,))
    pose_sigma: list[tuple[np.ndarray, np.ndarray]]
    shot_names: list[str]
    shot_poses: list[Transform | None]  # target's local frame -> camera 0
    used: np.ndarray  # (cameras, shots) bool
    reasons: dict[Key, str]
    rms: float
    warnings: list[str]
    start: RigStart
    relabelled: int
    x: np.ndarray
    problem: RigProblem
    intr0: np.ndarray
    covariance: np.ndarray | None

    def pose_in_reference(self, c: int) -> Transform:
        """Camera c's pose in camera 0's frame (p_0 = R p_c + t): what a static transform from
        camera 0's optical frame to camera c's publishes."""
        return self.extrinsics[c].inverse()

    def summary_lines(self) -> list[str]:
        lines = []
        both = int(np.sum(self.used.sum(0) >= 2))
        lines.append(f"shots: {self.used.shape[1]}, {both} used by two or more cameras; "
                     + ", ".join(f"{n} {int(self.used[c].sum())}" for c, n in enumerate(self.names))
                     + f" views; RMS {self.rms:.4f} px (edge distances; corners without edges)")
        for c, n in enumerate(self.names):
            r = self.cameras[c]
            s = r.std
            K = r.K

            def pm(k: str, v: float, s: dict[str, float] = s) -> str:
                return f"{v:.3f} +- {s[k]:.3f}" if k in s else f"{v:.3f}"

            lines.append(f"{n}: fx={pm('fx', K[0, 0])} fy={pm('fy', K[1, 1])} cx={pm('cx', K[0, 2])} "
                         f"cy={pm('cy', K[1, 2])} rms={r.rms:.4f}px views={r.n_used} {r.model}")
        for c in range(1, len(self.names)):
            E, (sr, st) = self.extrinsics[c], self.extrinsic_sigma[c]
            lines.append(f"{self.names[0]} -> {self.names[c]}: X_{self.names[c]} = R X_{self.names[0]} + T, "
                         f"T = [{', '.join(f'{v:.6f}' for v in E.translation)}] m, angle {E.angle_deg():.4f} deg; "
                         f"sigma {np.linalg.norm(sr):.5f} deg, {np.linalg.norm(st):.4f} mm")
        if self.relabelled:
            lines.append(f"{self.relabelled} view(s) relabelled by a symmetry of the target to agree with the other "
                         "cameras")
        return lines + [f"warning: {w}" for w in self.warnings]


def _checked(dets: list[list[Detection]], names: list[str], target: Target) -> None:
    if len(dets) < 2:
        raise RigError("a rig needs at least two cameras")
    if len(names) != len(dets) or len(set(names)) != len(names):
        raise RigError(f"one distinct name per camera, got {names}")
    if len({len(d) for d in dets}) != 1:
        raise RigError("every camera needs one detection per shot (a rejected one where it has no image)")
    if target.circles and len({c.center for c in target.circles}) == 1 and not target.boards:
        raise RigError(f"target {target.name!r} is a single ring: its rotation about its own axis is seen in no "
                       "view, so a shot does not tie two cameras' frames together; use a grid or a board")


def label_moves(target: Target, origin: tuple[float, float]) -> LabelMoves:
    """The relabellings a view of ``target`` may need (:class:`~.rig_start.LabelMoves`): its
    symmetries; for a target that is one grid and nothing else (whose views the detector labels up
    to a lattice move when it sees part of the grid), every lattice move."""
    syms = target_symmetries(target, origin)
    lattice = len(target.grids) == 1 and not (target.rings or target.discs or target.boards) \
        and np.allclose(origin, target.grids[0].origin)
    return LabelMoves(syms, target.grids[0].pitch if lattice else 0.0)


def _own_calibrations(dets: list[list[Detection]], target: Target, opt: CalibrationOptions, names: list[str]
                      ) -> list[CalibrationResult]:
    out = []
    for c, d in enumerate(dets):
        try:
            out.append(calibrate(d, target, opt))
        except CalibrationError as e:
            raise RigError(f"camera {names[c]}: {e}") from None
    return out


def _posed_views(dets: list[list[Detection]], own: list[CalibrationResult], target: Target, opt: CalibrationOptions,
                 origin: tuple[float, float]) -> tuple[dict[Key, ViewData], dict[Key, Transform], dict[Key, str]]:
    """Observations and pose (with the camera's own calibration: its refinement's, :func:`refined_poses`)
    of every view the camera used."""
    views: dict[Key, ViewData] = {}
    posed: dict[Key, Transform] = {}
    reasons: dict[Key, str] = {}
    for c, res in enumerate(own):
        cam = res.camera()
        known = refined_poses(res)
        for s, rep in enumerate(res.views):
            if not rep.used:
                reasons[(c, s)] = rep.reason or "not used"
                continue
            vd = observations(dets[c][s], target, origin, opt)
            try:
                posed[(c, s)] = known[s] if s in known else \
                    polished_pose(vd, camera_pose(dets[c][s], target, cam, origin), cam, opt, 6)
            except (CircularPointError, np.linalg.LinAlgError, ValueError) as e:
                reasons[(c, s)] = f"pose with the calibrated camera: {e}"
                continue
            views[(c, s)] = vd
    return views, posed, reasons


@dataclass
class _Fit:
    keys: list[Key]  # (camera, shot) of every view, camera by camera
    shots: list[int]  # shot of each shot block
    prob: RigProblem
    intr0: np.ndarray
    sol: LMResult


def _joint_fit(keys: list[Key], views: dict[Key, ViewData], extrinsics: list[Transform],
               shot_pose: dict[int, Transform], intr: list[np.ndarray], offsets: dict[Key, float],
               opt: CalibrationOptions, max_iter: int) -> _Fit:
    """Build the joint problem of the views ``keys`` and solve it from the given start."""
    lens, free_d = DISTORTION_CHOICES[opt.distortion]
    free = ("fx", "fy", "cx", "cy") + (() if opt.zero_skew else ("skew",)) + free_d
    n_cam = len(extrinsics)
    keys = sorted(keys)
    shots = sorted({s for _, s in keys})
    block = {s: i for i, s in enumerate(shots)}
    use_offsets = opt.edge_offsets and any(len(views[k].points) for k in keys)
    subs, view_shot = [], []
    for c in range(n_cam):
        ks = [k for k in keys if k[0] == c]
        subs.append(Problem([views[k] for k in ks], 6, free, use_offsets, LOSS_SCALE, (), None, lens))
        view_shot.append(np.array([block[s] for _, s in ks], int))
    prob = RigProblem(subs, view_shot, len(shots))
    ext = np.array([np.r_[E.rotvec, E.translation] for E in extrinsics])
    sp = np.array([np.r_[shot_pose[s].rotvec, shot_pose[s].translation] for s in shots])
    offs = [np.array([offsets.get(k, 0.0) for k in keys if k[0] == c]) for c in range(n_cam)]
    intr0 = np.concatenate(intr)
    x0 = prob.pack(intr, ext, sp, offs)
    sol = levenberg_marquardt(prob, x0, intr0, LOSS_SCALE, max_iter=max_iter)
    return _Fit(keys, shots, prob, intr0, sol)


def _start_intrinsics(res: CalibrationResult, opt: CalibrationOptions) -> np.ndarray:
    K, D = res.K, np.asarray(res.D, float).reshape(-1)
    lens, free_d = DISTORTION_CHOICES[opt.distortion]
    if len(D) != lens.n:
        D = np.r_[D, np.zeros(lens.n)][: lens.n]
    D = np.array([v if n in free_d else 0.0 for n, v in zip(lens.coefficients, D, strict=True)])
    return np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], 0.0 if opt.zero_skew else K[0, 1], *D])


def _view_rms(fit: _Fit) -> dict[Key, float]:
    """Edge RMS (corner RMS without edges) of every view in the joint fit."""
    out = {}
    f = fit.sol.fun
    j = 0
    for c, sub in enumerate(fit.prob.subs):
        fc = f[fit.prob.camera_rows(c)]
        for v in range(sub.nv):
            r = fc[sub.edge_slices[v]]
            if not len(r):
                cr = fc[sub.n_edge:].reshape(-1, 2)[sub.view_of_corner == v]
                out[fit.keys[j]] = float(np.sqrt(np.mean(np.sum(cr**2, 1)))) if len(cr) else 0.0
            else:
                out[fit.keys[j]] = float(np.sqrt(np.mean(r * r)))
            j += 1
    return out


def _state(fit: _Fit) -> tuple[list[Transform], dict[int, Transform], list[np.ndarray], dict[Key, float]]:
    """Extrinsics, shot poses, intrinsics and view offsets of a fit (to start another from)."""
    intr, ext, shots, offs = fit.prob.unpack(fit.sol.x, fit.intr0)
    E = [Transform.from_rotvec(e[:3], e[3:]) for e in ext]
    S = {s: Transform.from_rotvec(p[:3], p[3:]) for s, p in zip(fit.shots, shots, strict=True)}
    o, j = {}, 0
    for c in range(fit.prob.n_cam):
        for v in offs[c]:
            o[fit.keys[j]] = float(v)
            j += 1
    return E, S, intr, o


def calibrate_rig(dets: list[list[Detection]], target: Target, names: list[str],
                  options: RigOptions = RigOptions(), shot_names: list[str] | None = None
                  ) -> RigResult:
    """Calibrate a rig from ``dets[c][s]``, camera c's detection of shot s (module docstring)."""
    _checked(dets, names, target)
    opt = options.calibration
    n_cam, n_shots = len(dets), len(dets[0])
    shot_names = shot_names or [d.name or f"shot{s}" for s, d in enumerate(dets[0])]
    # refuse a rig that no shot connects before calibrating anything
    check_connected({(c, s): Transform.identity() for c in range(n_cam) for s in range(n_shots) if dets[c][s].ok},
                    names)
    own = _own_calibrations(dets, target, opt, names)
    sizes = {(r.width, r.height) for r in own}
    origin = target.local_origin
    views, posed, reasons = _posed_views(dets, own, target, replace(opt, max_points_per_view=options.points_per_view),
                                         origin)
    start = rig_start(posed, names, label_moves(target, origin), options.label_tolerance_deg,
                      options.label_tolerance_rel, options.relabel)
    reasons.update(start.dropped)
    keys = [k for k in posed if k not in start.dropped]
    n_relabelled = 0
    for k in keys:
        L = start.labels[k]
        if L.angle_deg() > 1e-6 or np.any(L.translation != 0):
            views[k], posed[k] = relabelled(views[k], L), posed[k] @ L
            n_relabelled += k[0] > 0
    shot_pose: dict[int, Transform] = {}
    for c, s in sorted(keys, key=lambda k: (k[1], list(start.parent).index(k[0]))):
        shot_pose.setdefault(s, start.extrinsics[c].inverse() @ posed[(c, s)])
    intr = [_start_intrinsics(r, opt) for r in own]
    offsets = {(c, s): float(own[c].views[s].edge_offset) for c, s in keys
               if np.isfinite(own[c].views[s].edge_offset)}
    fit = _joint_fit(keys, views, start.extrinsics, shot_pose, intr, offsets, opt, options.max_iter)
    if options.relabel:
        fit = _without_outliers(fit, views, reasons, names, opt, options)
    warnings = [f"{names[c]}: {w}" for c, r in enumerate(own) for w in r.warnings]
    if len(sizes) > 1:
        warnings.append("the cameras have different image sizes: " + ", ".join(f"{w}x{h}" for w, h in sorted(sizes)))
    for c in range(1, n_cam):
        n_shared = sum(1 for s in fit.shots if (c, s) in fit.keys and any((q, s) in fit.keys for q in range(n_cam)
                                                                          if q != c))
        if n_shared < 3:
            warnings.append(f"{names[c]} shares only {n_shared} shot(s) with the other cameras: its pose rests on "
                            "few shots; take more shots that both see")
    return _result(fit, own, names, shot_names, n_shots=n_shots, reasons=reasons, start=start,
                   relabelled=n_relabelled, warnings=warnings)


def _without_outliers(fit: _Fit, views: dict[Key, ViewData], reasons: dict[Key, str],
                      names: list[str], opt: CalibrationOptions, options: RigOptions) -> _Fit:
    """Leave out the views whose joint-fit RMS exceeds ``outlier_factor`` times the median and
    fit again (once); the rig must stay connected and every camera keep ``min_views`` views."""
    rms = _view_rms(fit)
    med = float(np.median(list(rms.values())))
    bad = [k for k, r in rms.items() if r > options.outlier_factor * max(med, 0.02)]
    if not bad:
        return fit
    keep = [k for k in fit.keys if k not in bad]
    for c in range(len(names)):
        if sum(k[0] == c for k in keep) < opt.min_views:
            return fit  # too few left to drop any: keep them (their RMS shows in the result)
    check_connected({k: Transform.identity() for k in keep}, names)
    for k in bad:
        reasons[k] = (f"outlier in the joint fit: edge RMS {rms[k]:.3f} px is {rms[k] / max(med, 1e-9):.1f}x the "
                      f"median {med:.3f} px (the target moved between the cameras' exposures, or a wrong detection)")
    E, S, intr, offs = _state(fit)
    return _joint_fit(keep, views, E, S, intr, offs, opt, options.max_iter)


def _covariance(fit: _Fit) -> np.ndarray | None:
    """The M-estimator's sandwich covariance of all parameters (:mod:`.covariance`): per camera, each
    view's edge rows and corner rows a group of their own variance times the camera's kappa."""
    prob, sol = fit.prob, fit.sol
    f = sol.fun
    n_rows = len(f)
    try:
        _, Jg, Jv = prob.evaluate(sol.x, fit.intr0)
        psi, dpsi = prob.loss_derivatives(f, LOSS_SCALE)
        var = np.zeros(n_rows)
        for c, sub in enumerate(prob.subs):
            rows = prob.camera_rows(c)
            share = round(len(sol.x) * (rows.stop - rows.start) / max(n_rows, 1))
            var[rows] = row_variances(sub, sub.views, f[rows], psi[rows], share)
        return sandwich_covariance(prob, f, Jg, Jv, dpsi, var)
    except np.linalg.LinAlgError:
        return None


def extrinsic_sigmas(E: Transform, cov6: np.ndarray) -> tuple[Sigmas, Sigmas]:
    """Per-axis sigmas (deg, mm) of an extrinsic E (X_c = R X_0 + t) from the covariance of its
    (phi, t): as small rotations about camera c's axes (d theta = J_l(phi) d phi) and translations;
    and of the camera's pose in camera 0's frame, E^-1 = (R^T, -R^T t), about camera 0's axes:
    d theta_0 = -R^T d theta, d t_0 = -R^T d t - R^T [t]_x d theta."""
    M = np.zeros((6, 6))
    M[:3, :3] = left_jacobian(E.rotvec)
    M[3:, 3:] = np.eye(3)
    C = M @ cov6 @ M.T
    R, t = E.R, E.translation
    G = np.zeros((6, 6))
    G[:3, :3] = -R.T
    G[3:, :3] = -R.T @ skew(t)
    G[3:, 3:] = -R.T
    C0 = G @ C @ G.T

    def sd(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.sqrt(np.maximum(np.diag(C), 0.0))
        return np.degrees(d[:3]), 1000 * d[3:]

    return sd(C), sd(C0)


def _camera_result(fit: _Fit, c: int, own: CalibrationResult, cov: np.ndarray | None, reasons: dict[Key, str]
                   ) -> CalibrationResult:
    """Camera c's part of the joint estimate as a :class:`CalibrationResult` (its pages of the report)."""
    prob, x = fit.prob, fit.sol.x
    sub = prob.subs[c]
    intr, ext, shots, offs = prob.unpack(x, fit.intr0)
    K = np.array([[intr[c][0], intr[c][4], intr[c][2]], [0, intr[c][1], intr[c][3]], [0, 0, 1.0]])
    D = intr[c][5:].copy()
    fc = fit.sol.fun[prob.camera_rows(c)]
    keys = [k for k in fit.keys if k[0] == c]
    reports = []
    rms_of = _view_rms(fit)
    for s, rep in enumerate(own.views):
        if (c, s) in keys:
            j = keys.index((c, s))
            reports.append(ViewReport(rep.name, True, "", rms_of[(c, s)], float(offs[c][j])))
        else:
            reports.append(ViewReport(rep.name, False, reasons.get((c, s), rep.reason or "not used")))
    std: dict[str, float] = {}
    if cov is not None:
        a = prob.intr_start[c]
        std = {sub.names[i]: float(np.sqrt(max(cov[a + k, a + k], 0.0))) for k, i in enumerate(sub.free)}
    rv, t, _, _ = prob.view_poses(c, ext, shots)
    er = fc[: sub.n_edge]
    cr = -fc[sub.n_edge:].reshape(-1, 2)
    edge_res = [er[sl] for sl in sub.edge_slices]
    rms = float(np.sqrt(np.mean(er * er))) if len(er) else float(np.sqrt(np.mean(np.sum(cr**2, 1))))
    poses = [np.r_[a, b] for a, b in zip(rv, t, strict=True)]
    res = replace(own, K=K, D=D, rms=rms, std=std, views=reports, poses=poses,
                  edge_points=[v.points for v in sub.views], edge_residuals=edge_res,
                  edge_circles=[v.circle_ids for v in sub.views], corner_points=[v.corners for v in sub.views],
                  corner_residuals=[cr[sub.view_of_corner == v] for v in range(sub.nv)], refinement=None,
                  warnings=[])
    return res


def _result(fit: _Fit, own: list[CalibrationResult], names: list[str],
            shot_names: list[str], n_shots: int, reasons: dict[Key, str], start: RigStart,
            relabelled: int, warnings: list[str]) -> RigResult:
    prob = fit.prob
    cov = _covariance(fit)
    _, ext, shots, _ = prob.unpack(fit.sol.x, fit.intr0)
    E = [Transform.from_rotvec(e[:3], e[3:]) for e in ext]
    ext_sd = [(np.zeros(3), np.zeros(3))] * len(E)
    pose_sd = [(np.zeros(3), np.zeros(3))] * len(E)
    for c in range(1, len(E)):
        a = prob.rig_start + 6 * (c - 1)
        cov6 = cov[a:a + 6, a:a + 6] if cov is not None else np.full((6, 6), np.nan)
        ext_sd[c], pose_sd[c] = extrinsic_sigmas(E[c], cov6)
    used = np.zeros((len(names), n_shots), bool)
    for c, s in fit.keys:
        used[c, s] = True
    shot_poses: list[Transform | None] = [None] * n_shots
    for s, p in zip(fit.shots, shots, strict=True):
        shot_poses[s] = Transform.from_rotvec(p[:3], p[3:])
    cams = [_camera_result(fit, c, own[c], cov, reasons) for c in range(len(names))]
    er = np.concatenate([np.concatenate(r.edge_residuals) for r in cams if r.edge_residuals])
    rms = float(np.sqrt(np.mean(er * er))) if len(er) else float(np.mean([r.rms for r in cams]))
    if not fit.sol.success:
        warnings.append(f"the joint refinement stopped early: {fit.sol.message}")
    return RigResult(names=names, cameras=cams, own=own, extrinsics=E, extrinsic_sigma=ext_sd, pose_sigma=pose_sd,
                     shot_names=shot_names, shot_poses=shot_poses, used=used,
                     reasons={k: v for k, v in reasons.items() if not used[k]}, rms=rms, warnings=warnings,
                     start=start, relabelled=relabelled, x=fit.sol.x, problem=prob, intr0=fit.intr0, covariance=cov)
