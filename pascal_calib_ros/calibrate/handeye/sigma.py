"""The sigmas of X and Y beyond the joint estimate's covariance: a delete-a-group jackknife over the
views, and the share of the arm's systematic position error (a Gaussian-process prior that no
session can measure)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...geometry import Transform, left_jacobian
from ...modes import HandEyeMode
from .chain import ChainProblem
from .closed_form import (
    chain_pose,
)
from .options import (
    HandEyeOptions,
)


@dataclass(frozen=True)
class Spread:
    """Per-axis standard deviations of X and Y: translation in mm along, rotation in degrees about
    the parent frame's axes, each (3,)."""

    x_mm: np.ndarray
    x_deg: np.ndarray
    y_mm: np.ndarray
    y_deg: np.ndarray

    def maximum(self, other: Spread) -> Spread:
        """The larger of two estimates, per axis."""
        return Spread(*(np.maximum(a, b) for a, b in zip(self.parts(), other.parts(), strict=True)))

    def root_sum_square(self, *others: Spread) -> Spread:
        """Independent shares added: sqrt(sum of squares), per axis."""
        return Spread(*(np.sqrt(sum(p**2 for p in parts)) for parts in zip(self.parts(), *(o.parts() for o in others),
                                                                             strict=True)))

    def parts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.x_mm, self.x_deg, self.y_mm, self.y_deg


def spread_of(cov: np.ndarray, xy: np.ndarray, base: int) -> Spread:
    """The per-axis sigmas of X and Y of a parameter covariance whose chain block starts at ``base``
    (X's rotation vector, X's translation, Y's rotation vector, Y's translation; ``xy`` their values:
    rotation vectors are turned into small rotations about the parent axes)."""
    def axes(off: int) -> tuple[np.ndarray, np.ndarray]:
        J = left_jacobian(xy[off:off + 3])  # d (small rotation about the parent axes) / d rvec
        b = base + off
        cr = J @ cov[b:b + 3, b:b + 3] @ J.T
        ct = cov[b + 3:b + 6, b + 3:b + 6]
        return 1000 * np.sqrt(np.maximum(np.diag(ct), 0)), np.degrees(np.sqrt(np.maximum(np.diag(cr), 0)))

    return Spread(*axes(0), *axes(6))


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
                    he: HandEyeOptions, A_pinv: np.ndarray | None = None) -> np.ndarray:
    """The parameters' covariance from the arm's systematic position error (:func:`arm_field_covariance`,
    ``he.arm_accuracy_mm`` over ``he.arm_accuracy_length``). The estimate moves with an error e of the
    reported tool positions by dx = -A^+ J_c^T (dr_c / de) e (A = J^T W J of the solution, J_c the
    chain rows' Jacobian, their weight 1; ``A_pinv``: A^+ if the caller has it); its covariance is
    S Sigma_e S^T. A uniform shift of every
    tool position moves the target's pose (eye in hand) or X itself (eye to hand: the camera sees
    the target where it is, the arm reports it elsewhere); what varies over the poses bends X."""
    xy = prob.chain_params(x)
    poses = np.array(prob.unpack(x, intr0)[2])
    mode = HandEyeMode.EYE_IN_HAND if prob.chain.eye_in_hand else HandEyeMode.EYE_TO_HAND
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
    S = -(np.linalg.pinv(A) if A_pinv is None else A_pinv) @ (prob.chain_dense_jacobian(xy, poses).T @ D)
    cov_e = arm_field_covariance(np.array([g.translation for g in G]), he.arm_accuracy_mm / 1000,
                                 he.arm_accuracy_length)
    return S @ cov_e @ S.T
