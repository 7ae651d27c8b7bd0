"""Closed forms of hand-eye calibration and the checks of the robot's motions.

The loop Y = M_i X C_i (module docstring of :mod:`.session`): Park & Martin, "Robot sensor
calibration: solving AX = XB on the Euclidean group", IEEE Trans. Robotics and Automation 10(5),
1994, over all view pairs; for an axisymmetric target (a single ring) linear least squares on its
centre and normal per view. Motions that leave X undetermined (fewer than 3 poses, pure
translations, a single rotation axis) are refused."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...geometry import Transform
from ...modes import HandEyeMode
from .options import (
    MIN_AXIS_SPREAD_DEG,
    MIN_MOTION_DEG,
    MIN_VIEWS,
    HandEyeError,
)


@dataclass(frozen=True)
class Motions:
    """Motion pairs A_k X = X B_k as arrays over the pairs k: the rotation vectors alpha_k of A_k and
    beta_k of B_k (P, 3), A_k's rotation matrices (P, 3, 3), the translations of A_k and B_k (P, 3)."""

    alpha: np.ndarray
    beta: np.ndarray
    RA: np.ndarray
    tA: np.ndarray
    tB: np.ndarray

    @staticmethod
    def of(A: list[Transform], B: list[Transform]) -> Motions:
        def arr(vals: list[np.ndarray], *shape: int) -> np.ndarray:
            return np.array(vals, float).reshape(-1, *shape)

        return Motions(arr([a.rotvec for a in A], 3), arr([b.rotvec for b in B], 3), arr([a.R for a in A], 3, 3),
                       arr([a.translation for a in A], 3), arr([b.translation for b in B], 3))


def park_martin(A: list[Transform], B: list[Transform]) -> Transform:
    """X with A_k X = X B_k in the least-squares sense of Park & Martin (IEEE TRA 1994)
    (:func:`park_martin_motions`)."""
    if len(A) != len(B) or len(A) < 2:
        raise HandEyeError("Park-Martin needs at least two motion pairs")
    return park_martin_motions(Motions.of(A, B))


def park_martin_motions(m: Motions) -> Transform:
    """Park & Martin's X: the rotation from the rotation vectors (R_X = (M^T M)^-1/2 M^T,
    M = sum beta alpha^T), then the translation by linear least squares on (R_A - I) t_X =
    R_X t_B - t_A. Needs two motions with non-parallel rotation axes."""
    if len(m.alpha) < 2:
        raise HandEyeError("Park-Martin needs at least two motion pairs")
    M = m.beta.T @ m.alpha  # sum_k beta_k alpha_k^T
    MtM = M.T @ M
    w, V = np.linalg.eigh(MtM)
    if w[0] <= 1e-12 * max(w[-1], 1e-300):
        raise HandEyeError("the motions rotate about a single axis: hand-eye is undetermined; rotate the tool "
                           "about at least two different axes between views")
    RX = V @ np.diag(1 / np.sqrt(w)) @ V.T @ M.T
    U, _, Vt = np.linalg.svd(RX)  # remove rounding
    RX = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    C = (m.RA - np.eye(3)).reshape(-1, 3)
    d = (m.tB @ RX.T - m.tA).reshape(-1)
    tX = np.linalg.lstsq(C, d, rcond=None)[0]
    return Transform.from_rt(RX, tX)


def _stack(T: list[Transform]) -> tuple[Rotation, np.ndarray]:
    return Rotation.concatenate([t.rotation for t in T]), np.array([t.translation for t in T]).reshape(-1, 3)


def chain_pose(robot_pose: Transform, mode: HandEyeMode) -> Transform:
    """M_i of the loop Y = M_i X C_i: the robot pose (eye in hand) or its inverse (eye to hand)."""
    return robot_pose if mode == HandEyeMode.EYE_IN_HAND else robot_pose.inverse()


def motion_pairs(M: list[Transform], C: list[Transform]) -> Motions:
    """The motions over all view pairs i < j: A = M_j^-1 M_i, B = C_j C_i^-1 (A X = X B), as arrays."""
    i, j = np.triu_indices(len(M), 1)
    RM, tM = _stack(M)
    RC, tC = _stack(C)
    RA = RM[j].inv() * RM[i]
    RB = RC[j] * RC[i].inv()
    return Motions(RA.as_rotvec().reshape(-1, 3), RB.as_rotvec().reshape(-1, 3), RA.as_matrix().reshape(-1, 3, 3),
                   RM[j].inv().apply(tM[i] - tM[j]).reshape(-1, 3), (tC[j] - RB.apply(tC[i])).reshape(-1, 3))


def target_from_chain(M: list[Transform], X: Transform, C: list[Transform]) -> Transform:
    """Y as the mean of M_i X C_i (rotation mean, translation mean), all views at once."""
    RM, tM = _stack(M)
    RC, tC = _stack(C)
    RMX = RM * X.rotation
    tMX = RM.apply(X.translation) + tM
    return Transform((RMX * RC).mean(), np.mean(RMX.apply(tC) + tMX, 0))


def hand_eye_closed_form(M: list[Transform], C: list[Transform]) -> tuple[Transform, Transform]:
    """(X, Y) from chain poses and full camera poses: Park-Martin over all pairs, Y averaged."""
    X = park_martin_motions(motion_pairs(M, C))
    return X, target_from_chain(M, X, C)


def ring_closed_form(M: list[Transform], centres: np.ndarray, normals: np.ndarray, length: float = 0.3
                     ) -> tuple[Transform, Transform]:
    """(X, Y) for an axisymmetric target seen as a centre c_i and a normal n_i (camera frame) per
    view: linear least squares on p = R_Mi (R_X c_i + t_X) + t_Mi and d = R_Mi R_X n_i (p, d the
    centre and normal in the fixed frame; R_X as 9 unknowns, then the nearest rotation), refined
    by nonlinear least squares on the same loop. Y's rotation about the target's axis is set to
    make the first view's rotation about its axis zero."""
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

    RM = np.array([m.R for m in M]).reshape(-1, 3, 3)
    tM = np.array([m.translation for m in M]).reshape(-1, 3)

    def res(p: np.ndarray) -> np.ndarray:
        # per view (M_k X c_k - p, L (R_Mk R_X n_k - d)), all views at once (unpack's X without a Transform)
        RX, pc = Rotation.from_rotvec(p[:3]).as_matrix(), p[6:9]
        d = np.array([np.sin(p[9]) * np.cos(p[10]), np.sin(p[9]) * np.sin(p[10]), np.cos(p[9])])
        pts = np.einsum("kij,kj->ki", RM, centres @ RX.T + p[3:6]) + tM - pc
        nrm = length * (np.einsum("kij,kj->ki", RM, normals @ RX.T) - d)
        return np.concatenate([pts, nrm], 1).ravel()

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


def check_robot_poses(poses: list[Transform], mode: HandEyeMode) -> None:
    """Refuse motions that leave X undetermined: fewer than 3 poses, no rotation between the poses
    (pure translations), or rotations about a single axis (the spread of the relative motions'
    axes below :data:`MIN_AXIS_SPREAD_DEG`)."""
    if len(poses) < MIN_VIEWS:
        raise HandEyeError(f"{len(poses)} view(s) with a robot pose; hand-eye needs at least {MIN_VIEWS} "
                           "(better 10-20, rotated about different axes)")
    for k, p in enumerate(poses):
        if not np.all(np.isfinite(p.matrix)):
            raise HandEyeError(f"robot pose {k} is not finite")
    RM, _ = _stack([chain_pose(p, mode) for p in poses])
    i, j = np.triu_indices(len(poses), 1)
    rv = (RM[j].inv() * RM[i]).as_rotvec().reshape(-1, 3)
    ang = np.linalg.norm(rv, axis=1)
    moved = np.degrees(ang) >= MIN_MOTION_DEG
    axes = rv[moved] / ang[moved, None]
    if not len(axes):
        raise HandEyeError(f"the robot poses differ by pure translations (no relative rotation above "
                           f"{MIN_MOTION_DEG:g} deg): the hand-eye rotation is undetermined; rotate the tool about "
                           "at least two different axes between views")
    # the largest angle between two axes (as lines) is at least the largest to the first axis and at most
    # twice it (the angle between lines is a metric): all pairs only when that does not decide
    to_first = float(np.degrees(np.arcsin(min(float(np.max(np.linalg.norm(np.cross(axes, axes[0]), axis=1))), 1.0))))
    if to_first >= MIN_AXIS_SPREAD_DEG:
        return
    a = axes if 2 * to_first >= MIN_AXIS_SPREAD_DEG else axes[:1]
    spread = float(np.max(np.linalg.norm(np.cross(a[:, None, :], a[None, :, :]), axis=2)))
    if np.degrees(np.arcsin(min(spread, 1.0))) < MIN_AXIS_SPREAD_DEG:
        raise HandEyeError(f"all robot motions rotate about a single axis (axes within {MIN_AXIS_SPREAD_DEG:g} deg "
                           "of each other): the translation along it is undetermined; rotate the tool about at "
                           "least two different axes between views")


def chain_disagreement(M: list[Transform], X: Transform, Y: Transform, C: list[Transform], mode: HandEyeMode
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Per view (mm, deg) of G_i^-1 G'_i: the measured robot pose against the one the images imply
    (eye in hand M^-1 Y C^-1 X^-1, eye to hand M X C Y^-1)."""
    if not M:
        return np.zeros(0), np.zeros(0)
    RM, tM = _stack(M)
    RC, tC = _stack(C)
    if mode == HandEyeMode.EYE_IN_HAND:
        R1, t1 = RM.inv() * Y.rotation, RM.inv().apply(Y.translation - tM)
        R2 = R1 * RC.inv()
        t2 = t1 - R2.apply(tC)
        t3 = t2 - (R2 * X.rotation.inv()).apply(X.translation)
        R3 = R2 * X.rotation.inv()
    else:
        R1, t1 = RM * X.rotation, RM.apply(X.translation) + tM
        R2, t2 = R1 * RC, R1.apply(tC) + t1
        R3 = R2 * Y.rotation.inv()
        t3 = t2 - R3.apply(Y.translation)
    mm = 1000 * np.linalg.norm(np.asarray(t3).reshape(-1, 3), axis=1)
    deg = np.degrees(np.linalg.norm(R3.as_rotvec().reshape(-1, 3), axis=1))
    return mm, deg


def complete_ring_poses(M: list[Transform], X: Transform, Y: Transform, C: list[Transform]) -> list[Transform]:
    """Each view's rotation about the ring's axis from the chain: the predicted pose
    X^-1 M^-1 Y turned minimally so that its z axis is the measured normal; the measured centre."""
    if not M:
        return []
    RP = X.rotation.inv() * Rotation.concatenate([m.rotation for m in M]).inv() * Y.rotation  # all views at once
    z_pred = RP.as_matrix().reshape(-1, 3, 3)[:, :, 2]
    z_meas = np.array([c.R[:, 2] for c in C])
    axis = np.cross(z_pred, z_meas)
    s = np.linalg.norm(axis, axis=1)
    ang = np.arctan2(s, np.sum(z_pred * z_meas, 1))
    rv = np.where(s[:, None] > 1e-12, axis / np.maximum(s, 1e-300)[:, None] * ang[:, None], 0.0)
    R = Rotation.from_rotvec(rv) * RP
    return [Transform(R[k], c.translation) for k, c in enumerate(C)]
