"""Hand-eye calibration: intrinsics, distortion, the camera-to-robot transform X and the target's
pose in one estimate from the circle edges (or checkerboard corners), with the robot chain as a
measurement.

Frames and the loop. Per view i the robot reports G_i = T_base_tool (the tool, or flange, in the
base frame). Eye in hand (camera on the tool): X = T_tool_camera, the target is fixed in the base
(Y = T_base_target). Eye to hand (camera fixed, the tool carries the target): X = T_base_camera,
Y = T_tool_target. With the chain pose M_i = G_i (eye in hand) or G_i^-1 (eye to hand) and the
view's target -> camera pose C_i, both modes are the loop Y = M_i X C_i (the convention of
OpenCV's calibrateHandEye and easy_handeye2: eye_in_hand gives camera -> gripper, eye_to_hand
camera -> base). X maps camera-frame points into its parent frame: it is what a
``static_transform_publisher`` with --frame-id parent --child-frame-id camera publishes.

Steps:

1. the intrinsic calibration of :func:`~.pipeline.calibrate` (its options, every lens model);
   each used view posed with that camera (circles: :func:`~.initial.pose_with_camera`;
   checkerboard only: PnP on the undistorted corners);
2. checks of the robot poses: at least 3 views with a pose, motions with two or more distinct
   rotation axes (pure translations or a single axis leave X undetermined);
3. symmetric targets: a grid that looks the same turned by 180 degrees may be labelled turned
   in some views; each view's labelling is chosen among the target's symmetries so that the
   motion pairs (A, B) agree in their screw invariants (rotation angle and the translation along
   the axis, which AX = XB preserves whatever X is), then again against the chain with X and Y
   from the closed form. A single ring (rotation about its axis invisible in any one view) is
   solved from its centre and normal per view, and the chain fixes each view's rotation about
   the axis;
4. closed form: Park & Martin, "Robot sensor calibration: solving AX = XB on the Euclidean
   group", IEEE Trans. Robotics and Automation 10(5), 1994: R_X = (M^T M)^-1/2 M^T with
   M = sum beta_k alpha_k^T (alpha, beta the rotation vectors of A_k, B_k), then t_X by linear
   least squares from (R_A - I) t_X = R_X t_B - t_A; over all view pairs. Views whose robot pose
   disagrees grossly with the images (a wrong frame, a pose from another view) are dropped with
   the reason (tested against X and Y from the other views);
5. the joint refinement (:class:`~.refine.ChainProblem`): X, Y, every view's camera pose and
   edge offset (and K, D only with ``HandEyeOptions.intrinsics="joint"``), with the edges' robust
   loss. By default ("hold") K and D are those of step 1 (the images alone) and held: a
   principal-point error acts like a constant camera rotation delta_c / f that X absorbs, and the
   arm's errors, fitted through the chain, drag the principal point (and with it X's rotation)
   further off than the images put it; the chain is a measurement of each camera pose
   with the arm's accuracy as its standard deviation (not a constraint: real arms are off by
   tenths of a millimetre, and deriving every camera pose from the robot pose makes the estimate
   follow the arm's errors). The arm's accuracy is estimated from the data (variance components:
   sigma^2 <- sum r^2 / redundancy of the chain rows, iterated) unless told otherwise. Neighbouring
   edge points (and checkerboard corners) err together: the edges weigh 1 / kappa against the
   chain, kappa from the residuals' autocorrelation (:func:`correlation_factor`), and their
   covariance is inflated by kappa;
6. the sigmas of X and Y: the larger per axis of the covariance of step 5 and a delete-a-group
   jackknife over the views (:func:`_jackknife`; it sees view-to-view detection biases and the
   arm's systematic errors that the residuals' covariance does not); with the intrinsics held,
   their share added: the images-only covariance of K, D carried through dx / dtheta =
   -A_xx^-1 A_xtheta (A the normal matrix of the refinement with the intrinsics free); and the
   share of the arm's systematic position error, which no session measures, from a stated prior
   (``HandEyeOptions.arm_accuracy_mm`` / ``arm_accuracy_length``, :func:`arm_field_share`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..detect.detection import Detection
from ..geometry.camera import Camera
from ..geometry.circular import CircularPointError
from ..geometry.lens import DISTORTION_CHOICES
from ..geometry.transform import Transform
from ..targets import Target
from .initial import pose_with_camera
from .pipeline import CalibrationError, CalibrationOptions, CalibrationResult, ViewReport, calibrate, observations
from .refine import ChainProblem, Problem, RobotChain, ViewData, levenberg_marquardt, shape_frame_of
from .uncertainty import correlation_factor

HAND_EYE_MODES = ("eye_in_hand", "eye_to_hand")
MIN_VIEWS = 3
MIN_MOTION_DEG = 2.0  # a relative motion rotating less than this carries no axis
MIN_AXIS_SPREAD_DEG = 5.0  # the largest angle between two motion axes must exceed this


class HandEyeError(CalibrationError):
    """The hand-eye session cannot be solved (too few views, degenerate motions, bad poses)."""


@dataclass
class HandEyeOptions:
    mode: str = "eye_in_hand"
    robot_sigma_mm: float = 0.1  # the arm's pose accuracy per axis (start value when estimated)
    robot_sigma_deg: float = 0.01
    estimate_robot_noise: bool = True  # estimate the arm's accuracy from the data (variance components)
    outlier_mm: float = 10.0  # a view whose chain disagrees by more than max(this, 8 x median) is dropped
    outlier_deg: float = 1.0
    jackknife_groups: int = 5  # the sigmas of X and Y also from a delete-a-group jackknife over the views (0: off)
    # "hold": K and D from the images alone, held in the chain refinement (the chain informs X, Y and the poses
    # only; the intrinsics' uncertainty is propagated into the sigmas of X and Y); "joint": estimated with the chain
    intrinsics: str = "hold"
    # the arm's systematic position error, which no session can measure (a smooth field over the workspace: a
    # Gaussian process, per base axis, of this standard deviation and correlation length); its share of the
    # sigmas of X and Y is added (0: left out). A prior from the arm's absolute accuracy, not a measurement
    arm_accuracy_mm: float = 0.2
    arm_accuracy_length: float = 0.3  # m

    def arm_accuracy_problem(self) -> str:
        """Why the arm-accuracy prior cannot be used ("" if it can)."""
        if np.isfinite(self.arm_accuracy_mm) and self.arm_accuracy_mm >= 0 and np.isfinite(self.arm_accuracy_length) \
                and self.arm_accuracy_length > 0:
            return ""
        return (f"arm accuracy {self.arm_accuracy_mm} mm over {self.arm_accuracy_length} m: give a finite accuracy "
                ">= 0 mm and a finite correlation length > 0 m")


@dataclass
class HandEyeResult:
    calibration: CalibrationResult
    mode: str
    hand_eye: Transform  # camera -> tool (eye_in_hand) or camera -> base (eye_to_hand)
    translation_std_mm: np.ndarray  # (3,) along the parent frame's axes
    rotation_std_deg: np.ndarray  # (3,) small rotations about the parent frame's axes
    target: Transform  # target (its YAML frame) -> base (eye_in_hand) or -> tool (eye_to_hand)
    views_used: int
    rms_px: float
    robot_error_mm: float  # the arm's pose error per axis the data imply (estimated sigma)
    robot_error_deg: float
    per_view: list[dict] = field(default_factory=list)  # name, used, reason, disagreement_mm, disagreement_deg
    warnings: list[str] = field(default_factory=list)
    closed_form: Transform | None = None  # X from the closed form (Park-Martin, or the ring's linear start)
    target_std_mm: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    target_std_deg: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    start_K: np.ndarray | None = None  # K of the plain intrinsic calibration (before the joint estimate)
    arm_share_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))  # of translation_std_mm: the arm prior's
    arm_share_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    arm_accuracy_mm: float = 0.0  # the prior used (HandEyeOptions.arm_accuracy_mm / _length)
    arm_accuracy_length: float = 0.0
    # of translation_std_mm / rotation_std_deg: the held intrinsics' share (their error moves X alike in every later
    # estimate with the same intrinsics: pascal-calib verify takes it out of the comparison)
    intrinsics_share_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    intrinsics_share_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def parent_frame_role(self) -> str:
        return "tool" if self.mode == "eye_in_hand" else "base"

    def summary(self) -> str:
        X = self.hand_eye
        t, q = X.translation, X.quat
        s_t, s_r = self.translation_std_mm, self.rotation_std_deg
        rpy = X.rotation.as_euler("xyz", degrees=True)
        lines = [f"hand-eye ({self.mode}): camera in the {self.parent_frame_role} frame",
                 "  translation [m]  " + "  ".join(f"{v:+.5f} +- {1e-3 * s:.5f}" for v, s in zip(t, s_t, strict=True)),
                 "  rotation [qx qy qz qw]  " + " ".join(f"{v:+.7f}" for v in q),
                 "  rotation rpy [deg]  " + " ".join(f"{v:+.4f}" for v in rpy)
                 + "   std about x y z [deg]  " + " ".join(f"{v:.4f}" for v in s_r),
                 f"  target in the {'base' if self.mode == 'eye_in_hand' else 'tool'} frame: "
                 f"t = [{', '.join(f'{v:+.5f}' for v in self.target.translation)}] m",
                 (f"  of the std, the arm's assumed systematic error ({self.arm_accuracy_mm:g} mm over "
                  f"{self.arm_accuracy_length:g} m): " + " ".join(f"{v:.3f}" for v in self.arm_share_mm) + " mm, "
                  + " ".join(f"{v:.4f}" for v in self.arm_share_deg) + " deg"
                  if self.arm_accuracy_mm > 0 else "  std without the arm's systematic error (arm accuracy 0)"),
                 f"views used: {self.views_used}/{len(self.per_view)}   RMS {self.rms_px:.4f} px   "
                 f"robot pose error the data imply: {self.robot_error_mm:.3f} mm, {self.robot_error_deg:.4f} deg "
                 "per axis",
                 "per view (chain vs images):"]
        for v in self.per_view:
            if v["used"]:
                lines.append(f"  used      {v['name']}  {v['disagreement_mm']:.3f} mm  {v['disagreement_deg']:.4f} deg")
            else:
                extra = (f"  ({v['disagreement_mm']:.1f} mm, {v['disagreement_deg']:.2f} deg)"
                         if np.isfinite(v.get("disagreement_mm", np.nan)) else "")
                lines.append(f"  rejected  {v['name']}  {v['reason']}{extra}")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


# -- closed forms ----------------------------------------------------------------------------

def park_martin(A: list[Transform], B: list[Transform]) -> Transform:
    """X with A_k X = X B_k in the least-squares sense of Park & Martin (IEEE TRA 1994): the
    rotation from the rotation vectors (R_X = (M^T M)^-1/2 M^T, M = sum beta alpha^T), then the
    translation by linear least squares. Needs two motions with non-parallel rotation axes."""
    if len(A) != len(B) or len(A) < 2:
        raise HandEyeError("Park-Martin needs at least two motion pairs")
    alpha = np.array([a.rotvec for a in A])
    beta = np.array([b.rotvec for b in B])
    M = beta.T @ alpha  # sum_k beta_k alpha_k^T
    MtM = M.T @ M
    w, V = np.linalg.eigh(MtM)
    if w[0] <= 1e-12 * max(w[-1], 1e-300):
        raise HandEyeError("the motions rotate about a single axis: hand-eye is undetermined; rotate the tool "
                           "about at least two different axes between views")
    RX = V @ np.diag(1 / np.sqrt(w)) @ V.T @ M.T
    U, _, Vt = np.linalg.svd(RX)  # remove rounding
    RX = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    C = np.concatenate([a.R - np.eye(3) for a in A])
    d = np.concatenate([RX @ b.translation - a.translation for a, b in zip(A, B, strict=True)])
    tX = np.linalg.lstsq(C, d, rcond=None)[0]
    return Transform.from_rt(RX, tX)


def chain_pose(robot_pose: Transform, mode: str) -> Transform:
    """M_i of the loop Y = M_i X C_i: the robot pose (eye in hand) or its inverse (eye to hand)."""
    return robot_pose if mode == "eye_in_hand" else robot_pose.inverse()


def motion_pairs(M: list[Transform], C: list[Transform]) -> tuple[list[Transform], list[Transform]]:
    """(A, B) over all view pairs i < j: A = M_j^-1 M_i, B = C_j C_i^-1 (A X = X B)."""
    A, B = [], []
    for i, j in itertools.combinations(range(len(M)), 2):
        A.append(M[j].inverse() @ M[i])
        B.append(C[j] @ C[i].inverse())
    return A, B


def target_from_chain(M: list[Transform], X: Transform, C: list[Transform]) -> Transform:
    """Y as the mean of M_i X C_i (rotation mean, translation mean)."""
    Ys = [m @ X @ c for m, c in zip(M, C, strict=True)]
    rot = Rotation.concatenate([y.rotation for y in Ys]).mean()
    return Transform(rot, np.mean([y.translation for y in Ys], 0))


def hand_eye_closed_form(M: list[Transform], C: list[Transform]) -> tuple[Transform, Transform]:
    """(X, Y) from chain poses and full camera poses: Park-Martin over all pairs, Y averaged."""
    A, B = motion_pairs(M, C)
    X = park_martin(A, B)
    return X, target_from_chain(M, X, C)


def ring_closed_form(M: list[Transform], centres: np.ndarray, normals: np.ndarray, length: float = 0.3
                     ) -> tuple[Transform, Transform]:
    """(X, Y) for an axisymmetric target seen as a centre c_i and a normal n_i (camera frame) per
    view: linear least squares on p = R_Mi (R_X c_i + t_X) + t_Mi and d = R_Mi R_X n_i (p, d the
    centre and normal in the fixed frame; R_X as 9 unknowns, then the nearest rotation), refined
    by nonlinear least squares on the same loop. Y's rotation about the target's axis is set to
    make the first view's rotation about its axis zero."""
    n = len(M)
    rows, rhs = [], []
    for m, c, nv in zip(M, centres, normals, strict=True):
        RM = m.R
        a = np.zeros((3, 18))
        a[:, 0:9] = -RM @ np.kron(np.eye(3), c[None, :])
        a[:, 9:12] = -RM
        a[:, 12:15] = np.eye(3)
        rows.append(a)
        rhs.append(m.translation)
        b = np.zeros((3, 18))
        b[:, 0:9] = -length * RM @ np.kron(np.eye(3), nv[None, :])
        b[:, 15:18] = length * np.eye(3)
        rows.append(b)
        rhs.append(np.zeros(3))
    z = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)[0]
    U, _, Vt = np.linalg.svd(z[:9].reshape(3, 3))
    RX = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    d0 = z[15:18] / max(np.linalg.norm(z[15:18]), 1e-12)
    ez = np.array([0.0, 0.0, 1.0])

    def unpack(p: np.ndarray) -> tuple[Transform, np.ndarray, np.ndarray]:
        X = Transform.from_rotvec(p[:3], p[3:6])
        th, ph = p[9], p[10]
        return X, p[6:9], np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])

    def res(p: np.ndarray) -> np.ndarray:
        X, pc, d = unpack(p)
        out = []
        for k in range(n):
            MX = M[k] @ X
            out.append(MX.apply(centres[k]) - pc)
            out.append(length * (MX.rotation.apply(normals[k]) - d))
        return np.concatenate(out)

    th0 = float(np.arccos(np.clip(d0[2], -1, 1)))
    p0 = np.r_[Rotation.from_matrix(RX).as_rotvec(), z[9:12], z[12:15], th0, np.arctan2(d0[1], d0[0])]
    sol = least_squares(res, p0, method="lm", x_scale="jac")
    X, pc, d = unpack(sol.x)
    # Y: origin at the centre, z along the normal, x from the first view's (arbitrary) x axis
    x0 = (M[0] @ X).rotation.apply(np.cross(ez, d) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0]))
    x0 = x0 - d * (x0 @ d)
    x0 /= np.linalg.norm(x0)
    RY = np.column_stack([x0, np.cross(d, x0), d])
    return X, Transform.from_rt(RY, pc)


# -- checks ----------------------------------------------------------------------------------

def check_robot_poses(poses: list[Transform], mode: str) -> None:
    """Refuse motions that leave X undetermined: fewer than 3 poses, no rotation between the poses
    (pure translations), or rotations about a single axis (the spread of the relative motions'
    axes below :data:`MIN_AXIS_SPREAD_DEG`)."""
    if len(poses) < MIN_VIEWS:
        raise HandEyeError(f"{len(poses)} view(s) with a robot pose; hand-eye needs at least {MIN_VIEWS} "
                           "(better 10-20, rotated about different axes)")
    for k, p in enumerate(poses):
        if not np.all(np.isfinite(p.matrix)):
            raise HandEyeError(f"robot pose {k} is not finite")
    M = [chain_pose(p, mode) for p in poses]
    axes = []
    for i, j in itertools.combinations(range(len(M)), 2):
        rv = (M[j].inverse() @ M[i]).rotvec
        ang = float(np.linalg.norm(rv))
        if np.degrees(ang) >= MIN_MOTION_DEG:
            axes.append(rv / ang)
    if not axes:
        raise HandEyeError(f"the robot poses differ by pure translations (no relative rotation above "
                           f"{MIN_MOTION_DEG:g} deg): the hand-eye rotation is undetermined; rotate the tool about "
                           "at least two different axes between views")
    a = np.array(axes)
    spread = float(np.max(np.linalg.norm(np.cross(a[:, None, :], a[None, :, :]), axis=2)))
    if np.degrees(np.arcsin(min(spread, 1.0))) < MIN_AXIS_SPREAD_DEG:
        raise HandEyeError(f"all robot motions rotate about a single axis (axes within {MIN_AXIS_SPREAD_DEG:g} deg "
                           "of each other): the translation along it is undetermined; rotate the tool about at "
                           "least two different axes between views")


# -- target symmetries -----------------------------------------------------------------------

def _square_colour(board: object, xy: np.ndarray) -> np.ndarray:
    x0, y0 = board.origin  # type: ignore[attr-defined]
    s = board.square_size  # type: ignore[attr-defined]
    i = np.floor((xy[:, 0] - x0) / s).astype(int)
    j = np.floor((xy[:, 1] - y0) / s).astype(int)
    return (i + j) % 2


def target_symmetries(target: Target, origin: tuple[float, float]) -> list[Transform]:
    """The rotations of the sheet (by 90, 180, 270 degrees about the features' centre) that map
    every circle (centre, radius, dark side) and every checkerboard corner and square colour onto
    the target again, as transforms of the refinement's local frame; identity first."""
    pts = [np.array([c.center for c in target.circles]).reshape(-1, 2)]
    for b in target.checkerboards:
        pts.append(b.corner_points())
    allp = np.concatenate(pts)
    if len(allp) == 0:
        return [Transform.identity()]
    ctr = (allp.min(0) + allp.max(0)) / 2
    out = [Transform.identity()]
    circ = np.array([[c.center[0], c.center[1], c.radius, float(c.dark_inside)] for c in target.circles]).reshape(-1, 4)
    for k in (1, 2, 3):
        th = k * np.pi / 2
        Rz = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])

        def rot(p: np.ndarray, Rz: np.ndarray = Rz) -> np.ndarray:
            return (p - ctr) @ Rz.T + ctr

        ok = True
        if len(circ):
            moved = np.c_[rot(circ[:, :2]), circ[:, 2:]]
            d = np.abs(moved[:, None, :] - circ[None, :, :]).max(2)
            ok = bool(np.all(d.min(1) < 1e-7))
        for b in target.checkerboards:
            cp = b.corner_points()
            mc = rot(cp)
            ok = ok and bool(np.all(np.abs(mc[:, None, :] - cp[None, :, :]).max(2).min(1) < 1e-7))
            # the colour of the squares must map too (sample square centres)
            x0, y0, x1, y1 = b.extent
            s = b.square_size
            g = np.stack(np.meshgrid(np.arange(x0 + s / 2, x1, s), np.arange(y0 + s / 2, y1, s)), -1).reshape(-1, 2)
            ok = ok and bool(np.all(_square_colour(b, g) == _square_colour(b, rot(g))))
        if ok:
            # as a local-frame transform: x_local = x - origin
            o = np.asarray(origin, float)
            R3 = np.eye(3)
            R3[:2, :2] = Rz
            t = np.r_[(ctr - o) - Rz @ (ctr - o), 0.0]
            out.append(Transform.from_rt(R3, t))
    return out


def _relabelled(view: ViewData, T: Transform) -> ViewData:
    """The view's observations under the labelling turned by the symmetry T (centres -> T^-1)."""
    Ti = T.inverse()

    def tf(p: np.ndarray) -> np.ndarray:
        if len(p) == 0:
            return p
        return Ti.apply(np.c_[p, np.zeros(len(p))])[:, :2]

    return replace(view, centers=tf(view.centers), corner_obj=tf(view.corner_obj))


def _screw(T: Transform) -> tuple[float, float]:
    """Rotation angle and translation along the axis: invariants of A X = X B."""
    rv = T.rotvec
    ang = float(np.linalg.norm(rv))
    pitch = float(T.translation @ rv / ang) if ang > 1e-9 else float(np.linalg.norm(T.translation))
    return ang, pitch


def _choose_labels(M: list[Transform], C: list[Transform], syms: list[Transform], ref: int) -> list[int]:
    """Per view the symmetry whose motion from/to view ``ref`` has the screw invariants of the
    robot's motion."""
    out = []
    for i in range(len(M)):
        if i == ref:
            out.append(0)
            continue
        a_ang, a_pitch = _screw(M[ref].inverse() @ M[i])
        best, arg = np.inf, 0
        for s, T in enumerate(syms):
            b_ang, b_pitch = _screw(C[ref] @ (C[i] @ T).inverse())
            score = abs(a_ang - b_ang) + abs(abs(a_pitch) - abs(b_pitch)) / 0.1
            if score < best:
                best, arg = score, s
        out.append(arg)
    return out


def chain_disagreement(M: list[Transform], X: Transform, Y: Transform, C: list[Transform], mode: str
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Per view (mm, deg) of G_i^-1 G'_i: the measured robot pose against the one the images imply."""
    mm, deg = [], []
    for m, c in zip(M, C, strict=True):
        d = m.inverse() @ Y @ c.inverse() @ X.inverse() if mode == "eye_in_hand" else m @ X @ c @ Y.inverse()
        mm.append(1000 * float(np.linalg.norm(d.translation)))
        deg.append(d.angle_deg())
    return np.array(mm), np.array(deg)


# -- the session -----------------------------------------------------------------------------

def _origin(target: Target) -> tuple[float, float]:
    return target.circles[0].center if target.circles else (0.0, 0.0)


def _camera_pose(det: Detection, target: Target, cam: Camera, origin: tuple[float, float]) -> Transform:
    """Target (local frame) -> camera for one view with the calibrated camera."""
    if det.edges:
        p = pose_with_camera(det, target, cam, origin)
        return Transform.from_rt(p.R, p.t)
    if det.corners is None or target.checkerboard is None:
        raise CircularPointError("no circles and no checkerboard corners")
    xy = cam.undistort_pixels(det.corners)
    obj = target.checkerboard.corner_points() - np.array(origin)
    ok = np.all(np.isfinite(xy), 1)
    if ok.sum() < 6:
        raise CircularPointError("fewer than 6 corners with a ray")
    found, rv, t = cv2.solvePnP(np.c_[obj[ok], np.zeros(ok.sum())].astype(np.float64), xy[ok].astype(np.float64),
                                np.eye(3), None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not found:
        raise CircularPointError("PnP on the checkerboard corners failed")
    return Transform.from_rotvec(np.ravel(rv), np.ravel(t))


def _polished_pose(view: ViewData, C: Transform, cam: Camera, opt: CalibrationOptions, dof: int) -> Transform:
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


def _rot_jacobian(rv: np.ndarray) -> np.ndarray:
    """d (small rotation about the parent axes) / d rvec (numerically)."""
    R0 = Rotation.from_rotvec(rv)
    J = np.zeros((3, 3))
    h = 1e-7
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        J[:, k] = (Rotation.from_rotvec(rv + e) * R0.inv()).as_rotvec() / h
    return J


def calibrate_hand_eye(dets: list[Detection], robot_poses: Sequence[Transform | None], target: Target, mode: str,
                       options: CalibrationOptions = CalibrationOptions(),  # noqa: B008 (frozen dataclass)
                       he: HandEyeOptions | None = None) -> HandEyeResult:
    """Joint intrinsic + hand-eye calibration (module docstring). ``robot_poses[i]`` is the tool
    pose in the base frame (T_base_tool) at view i, None if unknown (the view is refused)."""
    if mode not in HAND_EYE_MODES:
        raise HandEyeError(f"unknown hand-eye mode {mode!r}; choose one of {', '.join(HAND_EYE_MODES)}")
    he = replace(he, mode=mode) if he is not None else HandEyeOptions(mode)
    if len(robot_poses) != len(dets):
        raise HandEyeError(f"{len(robot_poses)} robot poses for {len(dets)} views: one per view (None if unknown)")
    for k, p in enumerate(robot_poses):
        if p is not None and not isinstance(p, Transform):
            raise HandEyeError(f"robot pose {k} is a {type(p).__name__}, not a Transform")
    if he.robot_sigma_mm <= 0 or he.robot_sigma_deg <= 0:
        raise HandEyeError("the robot's pose sigmas must be positive")
    if he.arm_accuracy_problem():
        raise HandEyeError(he.arm_accuracy_problem())
    dets = [d if p is not None or not d.ok else replace(d, reason="no robot pose for this view")
            for d, p in zip(dets, robot_poses, strict=True)]
    with_pose = [k for k, d in enumerate(dets) if d.ok]
    check_robot_poses([robot_poses[k] for k in with_pose], mode)  # type: ignore[misc]
    try:
        cal = calibrate(dets, target, options)
    except HandEyeError:
        raise
    except CalibrationError as e:
        raise HandEyeError(f"intrinsic calibration failed: {e}") from None
    reports = [replace(v) for v in cal.views]
    warnings = list(cal.warnings)
    cam = cal.camera()
    origin = _origin(target)
    axisymmetric = len({c.center for c in target.circles}) == 1 and not target.checkerboards
    views: list[ViewData] = []
    C: list[Transform] = []
    idx: list[int] = []
    for k, rep in enumerate(reports):
        if not rep.used:
            continue
        vd = observations(dets[k], target, origin, options)
        try:
            C.append(_polished_pose(vd, _camera_pose(dets[k], target, cam, origin), cam, options,
                                    5 if axisymmetric else 6))
        except (CircularPointError, np.linalg.LinAlgError, ValueError) as e:
            rep.used, rep.reason = False, f"pose with the calibrated camera: {e}"
            continue
        views.append(vd)
        idx.append(k)
    M = [chain_pose(robot_poses[k], mode) for k in idx]  # type: ignore[arg-type]
    if len(idx) < MIN_VIEWS:
        raise HandEyeError(f"only {len(idx)} view(s) with a robot pose and a camera pose; need {MIN_VIEWS}")
    check_robot_poses([robot_poses[k] for k in idx], mode)  # type: ignore[misc]

    def solve(sel: list[int]) -> tuple[Transform, Transform, list[Transform]]:
        Ms = [M[i] for i in sel]
        if axisymmetric:
            X, Y = ring_closed_form(Ms, np.array([C[i].translation for i in sel]),
                                    np.array([C[i].R[:, 2] for i in sel]))
            return X, Y, _complete_ring_poses(Ms, X, Y, [C[i] for i in sel])
        X, Y = hand_eye_closed_form(Ms, [C[i] for i in sel])
        return X, Y, [C[i] for i in sel]

    # symmetric targets: a consistent labelling through the robot chain
    syms = [] if axisymmetric else target_symmetries(target, origin)
    if len(syms) > 1:
        best: tuple[float, list[int]] | None = None
        for ref in range(min(3, len(idx))):
            lab = _choose_labels(M, C, syms, ref)
            Cl = [c @ syms[s] for c, s in zip(C, lab, strict=True)]
            X, Y = hand_eye_closed_form(M, Cl)
            mm, deg = chain_disagreement(M, X, Y, Cl, mode)
            score = float(np.median(mm) + 10 * np.median(deg))
            if best is None or score < best[0]:
                best = (score, lab)
        assert best is not None
        turns = [syms[s] for s in best[1]]
        Cl = [c @ T for c, T in zip(C, turns, strict=True)]
        X, Y = hand_eye_closed_form(M, Cl)
        for i in range(len(C)):  # again against the chain with X and Y of the closed form
            errs = []
            for T in syms:
                mm, deg = chain_disagreement([M[i]], X, Y, [Cl[i] @ T], mode)
                errs.append(mm[0] + 10 * deg[0])
            turns[i] = turns[i] @ syms[int(np.argmin(errs))]
        # the labelling of the whole session is free up to the symmetry (X is not affected; Y is turned): keep
        # the one most views were detected in
        g = min(syms, key=lambda G: sum((T @ G).angle_deg() > 1.0 for T in turns))
        turns = [T @ g for T in turns]
        warnings.append(f"target {target.name!r} looks the same turned by "
                        + ", ".join(f"{T.angle_deg():.0f}" for T in syms[1:])
                        + " deg: its pose is reported in the labelling most views were detected in")
        n_turned = 0
        for i, T in enumerate(turns):
            if T.angle_deg() > 1.0:
                n_turned += 1
                C[i] = C[i] @ T
                views[i] = _relabelled(views[i], T)
        if n_turned:
            warnings.append(f"{n_turned} view(s) were labelled turned by a symmetry of the target; relabelled "
                            "consistently with the robot chain")

    # gross disagreements between chain and images: each view against X and Y from the other views (leave one
    # out); the worst is dropped while it exceeds max(the floor, 8 x the others' median disagreement)
    active = list(range(len(idx)))
    disagreement: dict[int, tuple[float, float, str]] = {}
    while len(active) > MIN_VIEWS:
        worst: tuple[float, int, float, float, float, float] | None = None
        for j, a in enumerate(active):
            others = active[:j] + active[j + 1:]
            try:
                Xo, Yo, Co = solve(others)
            except HandEyeError:
                continue
            mo, do = chain_disagreement([M[i] for i in others], Xo, Yo, Co, mode)
            lim_mm = max(he.outlier_mm, 8 * float(np.median(mo)))
            lim_deg = max(he.outlier_deg, 8 * float(np.median(do)))
            cw = _complete_ring_poses([M[a]], Xo, Yo, [C[a]]) if axisymmetric else [C[a]]
            mw, dw = chain_disagreement([M[a]], Xo, Yo, cw, mode)
            score = max(mw[0] / lim_mm, dw[0] / lim_deg)
            if worst is None or score > worst[0]:
                worst = (score, j, float(mw[0]), float(dw[0]), lim_mm, lim_deg)
        if worst is None or worst[0] <= 1.0:
            break
        _, j, mw_, dw_, lim_mm, lim_deg = worst
        disagreement[active[j]] = (mw_, dw_, f"robot pose disagrees with the image: {mw_:.1f} mm, {dw_:.2f} deg "
                                             f"against the chain of the other views (limit {lim_mm:.1f} mm, "
                                             f"{lim_deg:.2f} deg): wrong pose, or the arm moved during the exposure")
        active = active[:j] + active[j + 1:]
    X0, Y0, C0 = solve(active)
    for i, (_, _, why) in disagreement.items():
        reports[idx[i]].used, reports[idx[i]].reason = False, why
    views = [views[i] for i in active]
    M = [M[i] for i in active]
    kept = [idx[i] for i in active]

    X, Y, Cf, sol_info = _refine_chain(views, M, X0, Y0, C0, cal, options, he, target, origin)
    (K, D, std, rms, offsets, view_rms, edge_res, sig_t, sig_r, sx_t, sx_r, sy_t, sy_r, success, intr_sd,
     corner_res, arm_sd) = sol_info
    if he.jackknife_groups >= 2 and len(views) >= 2 * he.jackknife_groups:
        # the jackknife holds the intrinsics when they are held ("hold"): their share is added after
        jx_t, jx_r, jy_t, jy_r = _jackknife(views, M, X, Y, Cf, replace(cal, K=K, D=D), options, he, target,
                                            origin, sig_t, sig_r)
        sx_t, sx_r = np.maximum(sx_t, jx_t), np.maximum(sx_r, jx_r)
        sy_t, sy_r = np.maximum(sy_t, jy_t), np.maximum(sy_r, jy_r)
    ix_t, ix_r, iy_t, iy_r = intr_sd
    ax_t, ax_r, ay_t, ay_r = arm_sd
    sx_t, sx_r = np.sqrt(sx_t**2 + ix_t**2 + ax_t**2), np.sqrt(sx_r**2 + ix_r**2 + ax_r**2)
    sy_t, sy_r = np.sqrt(sy_t**2 + iy_t**2 + ay_t**2), np.sqrt(sy_r**2 + iy_r**2 + ay_r**2)
    mm, deg = chain_disagreement(M, X, Y, Cf, mode)
    for j, k in enumerate(kept):
        reports[k].used, reports[k].reason = True, ""
        reports[k].rms, reports[k].edge_offset = float(view_rms[j]), float(offsets[j])
    per_view = []
    pos = {k: j for j, k in enumerate(kept)}
    dis = {idx[i]: v for i, v in disagreement.items()}
    for k, rep in enumerate(reports):
        if k in pos:
            per_view.append({"name": rep.name, "used": True, "reason": "", "disagreement_mm": float(mm[pos[k]]),
                             "disagreement_deg": float(deg[pos[k]])})
        else:
            d_mm, d_deg = (dis[k][0], dis[k][1]) if k in dis else (float("nan"), float("nan"))
            per_view.append({"name": rep.name, "used": False, "reason": rep.reason or "not used",
                             "disagreement_mm": d_mm, "disagreement_deg": d_deg})
    if not success:
        warnings.append("the joint refinement stopped early")
    to_yaml = Transform.from_rt(np.eye(3), [-origin[0], -origin[1], 0.0])  # YAML frame -> local frame
    calib = replace(cal, K=K, D=D, rms=rms, std=std, views=reports, warnings=warnings,
                    poses=[np.r_[c.rotvec, c.translation] for c in Cf],
                    edge_points=[v.points for v in views], edge_residuals=edge_res,
                    edge_circles=[v.circle_ids for v in views], corner_points=[v.corners for v in views],
                    corner_residuals=corner_res)
    if axisymmetric:
        warnings.append("a single ring: the target's rotation about its axis is not observable (reported "
                        "arbitrarily); X is not affected")
    return HandEyeResult(calib, mode, X, sx_t, sx_r, Y @ to_yaml, len(kept), rms, sig_t, sig_r, per_view, warnings,
                         X0, sy_t, sy_r, cal.K.copy(), ax_t, ax_r, he.arm_accuracy_mm, he.arm_accuracy_length,
                         intrinsics_share_mm=ix_t, intrinsics_share_deg=ix_r)


def _complete_ring_poses(M: list[Transform], X: Transform, Y: Transform, C: list[Transform]) -> list[Transform]:
    """Each view's rotation about the ring's axis from the chain: the predicted pose
    X^-1 M^-1 Y turned minimally so that its z axis is the measured normal; the measured centre."""
    out = []
    for m, c in zip(M, C, strict=True):
        P = X.inverse() @ m.inverse() @ Y
        z_pred, z_meas = P.R[:, 2], c.R[:, 2]
        axis = np.cross(z_pred, z_meas)
        s = float(np.linalg.norm(axis))
        turn = Rotation.from_rotvec(axis / s * np.arctan2(s, float(z_pred @ z_meas))) if s > 1e-12 \
            else Rotation.identity()
        out.append(Transform(turn * P.rotation, c.translation))
    return out


def _jackknife(views: list[ViewData], M: list[Transform], X: Transform, Y: Transform, C: list[Transform],
               cal: CalibrationResult, opt: CalibrationOptions, he: HandEyeOptions, target: Target,
               origin: tuple[float, float], sig_mm: float, sig_deg: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-axis sigmas of X and Y (mm, deg) from a delete-a-group jackknife: the views in
    ``he.jackknife_groups`` interleaved groups, the joint estimate without each group (from the full
    solution, the arm's sigmas held), var = (g - 1) / g sum (theta_-k - mean)^2. It sees what
    the residuals' covariance does not: detection biases that differ from view to view, the
    arm's systematic errors."""
    g = he.jackknife_groups
    he_k = replace(he, robot_sigma_mm=sig_mm, robot_sigma_deg=sig_deg, estimate_robot_noise=False,
                   jackknife_groups=0)
    xs, ys = [], []
    for k in range(g):
        keep = [i for i in range(len(views)) if i % g != k]
        Xk, Yk, _, _ = _refine_chain([views[i] for i in keep], [M[i] for i in keep], X, Y, [C[i] for i in keep],
                                     cal, opt, he_k, target, origin, covariance=False)
        xs.append(Xk)
        ys.append(Yk)

    def spread(ts: list[Transform], ref: Transform) -> tuple[np.ndarray, np.ndarray]:
        dt = np.array([1000 * (t.translation - ref.translation) for t in ts])
        dr = np.array([np.degrees((t.rotation * ref.rotation.inv()).as_rotvec()) for t in ts])
        f = (g - 1) / g
        return np.sqrt(f * np.sum((dt - dt.mean(0)) ** 2, 0)), np.sqrt(f * np.sum((dr - dr.mean(0)) ** 2, 0))

    return (*spread(xs, X), *spread(ys, Y))


def _refine_chain(views: list[ViewData], M: list[Transform], X0: Transform, Y0: Transform, C0: list[Transform],
                  cal: CalibrationResult, opt: CalibrationOptions, he: HandEyeOptions, target: Target,
                  origin: tuple[float, float], covariance: bool = True
                  ) -> tuple[Transform, Transform, list[Transform], tuple]:
    """The joint refinement with the robot chain as a measurement; the arm's sigmas by variance
    components (iterated) when asked for. Returns X, Y, the camera poses and the figures."""
    lens, free_d = DISTORTION_CHOICES[opt.distortion]
    free = ("fx", "fy", "cx", "cy") + (() if opt.zero_skew else ("skew",)) + free_d
    shape = tuple(opt.target_shape)
    frame = None
    if shape:
        pts = [np.array([c.center for c in target.circles]).reshape(-1, 2)]
        pts += [b.corner_points() for b in target.checkerboards]
        frame = shape_frame_of(np.concatenate(pts) - np.array(origin))
    K0, D0 = cal.K, np.asarray(cal.D, float).reshape(-1)
    if len(D0) != lens.n:
        D0 = np.r_[D0, np.zeros(lens.n)][: lens.n]
    intr0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], 0.0 if opt.zero_skew else K0[0, 1], *D0])
    scale = max(float(cal.rms), 0.01) if np.isfinite(cal.rms) else 0.05
    sig_t, sig_r = he.robot_sigma_mm / 1000, np.radians(he.robot_sigma_deg)
    chain = RobotChain(M, he.mode == "eye_in_hand", sig_r, sig_t, scale)
    hold = he.intrinsics == "hold"
    prob = ChainProblem(views, () if hold else free, opt.edge_offsets, chain, 0.3, shape, frame, lens)
    xy = np.r_[X0.rotvec, X0.translation, Y0.rotvec, Y0.translation]
    x = prob.pack_chain(intr0, [np.r_[c.rotvec, c.translation] for c in C0], np.zeros(len(views)), xy)
    rows_r, rows_t = prob.chain_rows()
    kappa = 1.0
    for it in range(8 if he.estimate_robot_noise else 2):
        chain.sigma_rot, chain.sigma_trans = sig_r, sig_t
        sol = levenberg_marquardt(prob, x, intr0, 0.3, max_iter=100)
        x = sol.x
        # the edge scale (px) and the edges' correlation: what a chain residual of one sigma weighs
        n_rob = prob.n_robust
        s_edge = float(np.sqrt(np.sum(sol.weights[:n_rob] * sol.fun[:n_rob] ** 2) / max(n_rob - len(x), 1)))
        kappa_new = correlation_factor(prob, views, sol.fun)
        if not he.estimate_robot_noise:
            if it == 0:
                kappa, chain.scale = kappa_new, max(s_edge * np.sqrt(kappa_new), 1e-3)
                continue
            break
        Ainv = np.linalg.pinv(sol.normal_matrix)
        new = []
        for rows, sig in ((rows_r, sig_r), (rows_t, sig_t)):
            w = np.zeros(len(sol.fun))
            w[rows] = 1.0
            Ag, _ = prob.normal_equations(sol.fun, *prob.evaluate(x, intr0)[1:], w)
            red = max(len(rows) - float(np.trace(Ainv @ Ag)), 1.0)
            chi2 = float(np.sum((sol.fun[rows] / chain.scale) ** 2))
            new.append(sig * np.sqrt(chi2 / red))
        new_r = max(new[0], np.radians(1e-4))
        new_t = max(new[1], 1e-6)
        new_scale = max(s_edge * np.sqrt(kappa_new), 1e-3)
        done = (abs(new_r / sig_r - 1) < 0.05 and abs(new_t / sig_t - 1) < 0.05
                and abs(new_scale / chain.scale - 1) < 0.05)
        sig_r, sig_t = new_r, new_t
        chain.scale, kappa = new_scale, kappa_new
        if done:
            break
    chain.sigma_rot, chain.sigma_trans = sig_r, sig_t
    intr, _, poses, offsets = prob.unpack(x, intr0)
    xy = prob.chain_params(x)
    if not covariance:
        return Transform.from_rotvec(xy[0:3], xy[3:6]), Transform.from_rotvec(xy[6:9], xy[9:12]), [], ()
    f = sol.fun
    w = sol.weights
    # the normal matrix weighs the edges as independent points of variance s_edge^2 and the chain in units of
    # chain.scale = s_edge sqrt(kappa): the covariance is its inverse times kappa s_edge^2 (edges of variance
    # kappa s_edge^2, the chain of its sigmas)
    n_rob = prob.n_robust
    s2 = float(np.sum(w[:n_rob] * f[:n_rob] ** 2) / max(n_rob - len(x), 1)) if n_rob else 1.0
    cov = np.linalg.pinv(sol.normal_matrix) * s2 * kappa
    names = prob.names
    std = {names[i]: float(np.sqrt(max(cov[k, k], 0.0))) for k, i in enumerate(prob.free)}
    b = prob.n_base

    def stds(off: int, rv: np.ndarray, cov: np.ndarray = cov) -> tuple[np.ndarray, np.ndarray]:
        J = _rot_jacobian(rv)
        cr = J @ cov[b + off:b + off + 3, b + off:b + off + 3] @ J.T
        ct = cov[b + off + 3:b + off + 6, b + off + 3:b + off + 6]
        return 1000 * np.sqrt(np.maximum(np.diag(ct), 0)), np.degrees(np.sqrt(np.maximum(np.diag(cr), 0)))

    if hold:
        # the intrinsics' error moves X and Y by dx/dtheta = -A_rr^-1 A_rtheta (A of the joint problem with the
        # intrinsics free); their covariance is that of the images alone (the chain rows weighed zero)
        shape_v = prob.unpack(x, intr0)[1]
        full = ChainProblem(views, free, opt.edge_offsets, chain, 0.3, shape, frame, lens)
        xf = full.pack_chain(intr, [p.copy() for p in poses], offsets, xy, shape_v)
        ff, Jg_f, Jv_f = full.evaluate(xf, intr)
        wf = full.robust_weights(ff, 0.3)
        Af, _ = full.normal_equations(ff, Jg_f, Jv_f, wf)
        wi = wf.copy()
        wi[full.n_robust:] = 0.0
        Ai, _ = full.normal_equations(ff, Jg_f, Jv_f, wi)
        nf = len(full.free)
        cov_th = np.linalg.pinv(Ai)[:nf, :nf] * s2 * kappa
        S = -np.linalg.pinv(Af[nf:, nf:]) @ Af[nf:, :nf]
        cov_i = S @ cov_th @ S.T
        std = {names[i]: float(np.sqrt(max(cov_th[k, k], 0.0))) for k, i in enumerate(full.free)}
    else:
        cov_i = np.zeros_like(cov)
    sx_t, sx_r = stds(0, xy[0:3])
    sy_t, sy_r = stds(6, xy[6:9])
    cov_a = arm_field_share(prob, x, intr0, sol.normal_matrix, M, he) if he.arm_accuracy_mm > 0 else np.zeros_like(cov)
    arm_sd = (*stds(0, xy[0:3], cov_a), *stds(6, xy[6:9], cov_a))
    # the intrinsics' share (zero when they are estimated with the chain: then in cov)
    ix_t, ix_r = stds(0, xy[0:3], cov_i)
    iy_t, iy_r = stds(6, xy[6:9], cov_i)
    K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    D = intr[5:].copy()
    er = f[: prob.n_edge]
    edge_res = [er[s] for s in prob.edge_slices]
    if prob.n_edge:
        rms = float(np.sqrt(np.mean(er**2)))
        view_rms = np.array([np.sqrt(np.mean(r * r)) if len(r) else 0.0 for r in edge_res])
    else:
        cr = f[prob.n_edge:prob.n_robust].reshape(-1, 2)
        rms = float(np.sqrt(np.mean(np.sum(cr**2, 1))))
        view_rms = np.array([float(np.sqrt(np.mean(np.sum(cr[prob.view_of_corner == i] ** 2, 1))))
                             for i in range(prob.nv)])
    corners = -f[prob.n_edge:prob.n_robust].reshape(-1, 2)  # observed - predicted, as refine's
    corner_res = [corners[prob.view_of_corner == i] for i in range(prob.nv)]
    # robot error the data imply: the estimated sigmas, or the RMS of the disagreements per axis
    if he.estimate_robot_noise:
        err_mm, err_deg = 1000 * sig_t, float(np.degrees(sig_r))
    else:
        drv, dt = prob.chain_deltas(xy, poses)
        err_mm, err_deg = 1000 * float(np.sqrt(np.mean(dt**2))), float(np.degrees(np.sqrt(np.mean(drv**2))))
    X = Transform.from_rotvec(xy[0:3], xy[3:6])
    Y = Transform.from_rotvec(xy[6:9], xy[9:12])
    Cf = [Transform.from_rotvec(p[:3], p[3:6]) for p in poses]
    return X, Y, Cf, (K, D, std, rms, offsets, view_rms, edge_res, err_mm, err_deg, sx_t, sx_r, sy_t, sy_r,
                      bool(sol.success), (ix_t, ix_r, iy_t, iy_r), corner_res, arm_sd)


def arm_field_covariance(positions: np.ndarray, sigma_m: float, length_m: float) -> np.ndarray:
    """(3V, 3V) covariance of an arm's systematic position error at the tool positions ``positions``
    (V, 3): per base axis an independent Gaussian process with the squared-exponential kernel
    sigma^2 exp(-|p_i - p_j|^2 / (2 L^2)) (Rasmussen & Williams, "Gaussian Processes for Machine
    Learning", 2006, ch. 4), the smooth field that link-length and joint-offset errors leave over a
    workspace. Rows ordered view-major (view i, axis a -> 3 i + a)."""
    p = np.asarray(positions, float).reshape(-1, 3)
    d2 = np.sum((p[:, None, :] - p[None, :, :]) ** 2, -1)
    return np.kron(sigma_m**2 * np.exp(-d2 / (2 * length_m**2)), np.eye(3))


def arm_field_share(prob: ChainProblem, x: np.ndarray, intr0: np.ndarray, A: np.ndarray, M: list[Transform],
                    he: HandEyeOptions) -> np.ndarray:
    """The parameters' covariance from the arm's systematic position error (:func:`arm_field_covariance`,
    ``he.arm_accuracy_mm`` over ``he.arm_accuracy_length``). The estimate moves with an error e of the
    reported tool positions by dx = -A^+ J_c^T (dr_c / de) e (A = J^T W J of the solution, J_c the
    chain rows' Jacobian, their weight 1); its covariance is S Sigma_e S^T. A uniform shift of every
    tool position moves the target's pose (eye in hand) or X itself (eye to hand: the camera sees
    the target where it is, the arm reports it elsewhere); what varies over the poses bends X."""
    xy = prob.chain_params(x)
    poses = np.array(prob.unpack(x, intr0)[2])
    mode = "eye_in_hand" if prob.chain.eye_in_hand else "eye_to_hand"
    G = [chain_pose(m, mode) for m in M]  # the tool poses (chain_pose is its own inverse)
    nv, h = len(G), 1e-6
    D = np.zeros((6 * nv, 3 * nv))
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        moved = [[chain_pose(Transform(g.rotation, g.translation + sgn * e), mode) for g in G] for sgn in (1, -1)]
        d = (prob.chain_residuals(xy, poses, moved[0]) - prob.chain_residuals(xy, poses, moved[1])) / (2 * h)
        for i in range(nv):
            D[6 * i:6 * i + 6, 3 * i + a] = d[i]
    S = -np.linalg.pinv(A) @ (prob.chain_dense_jacobian(xy, poses).T @ D)
    cov_e = arm_field_covariance(np.array([g.translation for g in G]), he.arm_accuracy_mm / 1000,
                                 he.arm_accuracy_length)
    return S @ cov_e @ S.T


__all__ = ["HAND_EYE_MODES", "HandEyeError", "HandEyeOptions", "HandEyeResult", "ViewReport", "calibrate_hand_eye",
           "check_robot_poses", "park_martin"]
