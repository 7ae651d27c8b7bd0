"""Derivatives of the rotation-vector (Rodrigues) parametrisation, for chaining pose Jacobians.

With R = exp([phi]_x) (phi a rotation vector, theta = |phi|), a change d phi turns R on the left
by J_l(phi) d phi and on the right by J_r(phi) d phi:
exp([phi + d]_x) = exp([J_l d]_x) exp([phi]_x) = exp([phi]_x) exp([J_r d]_x) to first order, with

    J_l(phi) = I + (1 - cos theta) / theta^2 [phi]_x + (theta - sin theta) / theta^3 [phi]_x^2,
    J_l^-1(phi) = I - 1/2 [phi]_x + (1 / theta^2 - cot(theta / 2) / (2 theta)) [phi]_x^2,
    J_r(phi) = J_l(-phi) = J_l(phi)^T

(Barfoot, "State Estimation for Robotics", 2017, section 7.1.5; Sola et al., "A micro Lie theory
for state estimation in robotics", arXiv:1812.01537, eqs. 143-146). J_l^-1 is finite up to
theta = pi (the largest angle a rotation vector needs).

Composition (:func:`compose_with_jacobians`): R = R_a R_b, t = R_a t_b + t_a has
d phi / d phi_a = J_l^-1(phi) J_l(phi_a), d phi / d phi_b = J_r^-1(phi) J_r(phi_b),
d t / d phi_a = -[R_a t_b]_x J_l(phi_a), d t / d t_a = I, d t / d t_b = R_a.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

SMALL_ANGLE = 1e-4  # rad: below it the series of the coefficients are used


def skew(v: np.ndarray) -> np.ndarray:
    """[v]_x of vectors (..., 3): (..., 3, 3) with [v]_x w = v x w."""
    v = np.asarray(v, float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """J_l of rotation vectors (..., 3): (..., 3, 3) (module docstring)."""
    phi = np.asarray(phi, float)
    th = np.linalg.norm(phi, axis=-1)
    small = th < SMALL_ANGLE
    t = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24, (1 - np.cos(t)) / t**2)
    b = np.where(small, 1.0 / 6 - th**2 / 120, (t - np.sin(t)) / t**3)
    P = skew(phi)
    return np.eye(3) + a[..., None, None] * P + b[..., None, None] * (P @ P)


def left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """J_l^-1 of rotation vectors (..., 3) with |phi| <= pi: (..., 3, 3) (module docstring)."""
    phi = np.asarray(phi, float)
    th = np.linalg.norm(phi, axis=-1)
    small = th < SMALL_ANGLE
    t = np.where(small, 1.0, th)
    c = np.where(small, 1.0 / 12 + th**2 / 720, 1 / t**2 - np.cos(t / 2) / (2 * t * np.sin(t / 2)))
    P = skew(phi)
    return np.eye(3) - 0.5 * P + c[..., None, None] * (P @ P)


def compose_with_jacobians(rv_a: np.ndarray, t_a: np.ndarray, rv_b: np.ndarray, t_b: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The poses a o b (p -> R_a (R_b p + t_b) + t_a) of rotation vectors and translations
    (V, 3) each, as (rotation vectors (V, 3), translations (V, 3)), and the Jacobians of the
    6-vector (phi, t) of the result with respect to (phi_a, t_a) and to (phi_b, t_b): (V, 6, 6)
    each (module docstring)."""
    Ra, Rb = Rotation.from_rotvec(rv_a), Rotation.from_rotvec(rv_b)
    rv = (Ra * Rb).as_rotvec().reshape(-1, 3)
    Rb_t = Ra.apply(t_b).reshape(-1, 3)
    t = Rb_t + np.asarray(t_a, float).reshape(-1, 3)
    Jl_a = left_jacobian(rv_a)
    Jinv = left_jacobian_inverse(rv)
    n = len(rv)
    Da = np.zeros((n, 6, 6))
    Db = np.zeros((n, 6, 6))
    Da[:, :3, :3] = Jinv @ Jl_a
    Da[:, 3:, :3] = -skew(Rb_t) @ Jl_a
    Da[:, 3:, 3:] = np.eye(3)
    # J_r^-1(phi) J_r(phi_b) = J_l^-1(phi)^T J_l(phi_b)^T
    Db[:, :3, :3] = np.transpose(Jinv, (0, 2, 1)) @ np.transpose(left_jacobian(rv_b), (0, 2, 1))
    Db[:, 3:, 3:] = Ra.as_matrix().reshape(-1, 3, 3)
    return rv, t, Da, Db
