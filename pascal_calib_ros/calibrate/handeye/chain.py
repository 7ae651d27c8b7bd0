"""The robot chain as a measurement: a :class:`~.problem.Problem` with six chain rows per view
(:class:`RobotChain`, :class:`ChainProblem`), for the joint hand-eye refinement."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ...geometry import PLUMB_BOB, LensModel
from ..solver.observations import ViewData
from ..solver.problem import Problem


@dataclass
class RobotChain:
    """A robot chain as a *measurement* of every view's camera pose (calibrate/handeye.py).

    Per view i the chain pose M_i (eye in hand: T_base_tool, the robot's pose; eye to hand:
    T_tool_base, its inverse), the hand-eye transform X (camera -> tool, or camera -> base) and the
    target's pose Y (target's local frame -> base, or -> tool) close the loop Y = M_i X C_i, with
    C_i the view's target -> camera pose. The robot pose the images imply, G'_i, is compared with
    the measured one G_i: delta_i = G_i^-1 G'_i (eye in hand: M_i^-1 Y C_i^-1 X^-1; eye to hand:
    M_i X C_i Y^-1), six residuals per view, (rotation vector / sigma_rot, translation /
    sigma_trans) times ``scale`` (pixels per sigma, so that they weigh like edge residuals).
    Quadratic loss (a Gaussian arm), not the edges' robust one."""

    chain: list[Any]  # geometry.transform.Transform M_i per view
    eye_in_hand: bool
    sigma_rot: float  # rad per axis
    sigma_trans: float  # m per axis
    scale: float = 1.0  # px per sigma


class ChainProblem(Problem):
    """:class:`Problem` with a robot chain: x = [free intrinsics, shape parameters, X (rvec, t),
    Y (rvec, t), view 0 (6-dof pose, offset), ...]; rows = edge points, corners, then six chain
    rows per view (:class:`RobotChain`). The chain rows' Jacobian is by central differences
    (vectorised over the views: a handful of rotations per parameter)."""

    N_CHAIN = 12

    def __init__(self, views: list[ViewData], free_intrinsics: tuple[str, ...], use_offsets: bool,
                 chain: RobotChain, loss_scale: float = 0.3, shape: tuple[str, ...] = (),
                 shape_frame: tuple[float, float, float, float] | None = None, lens: LensModel = PLUMB_BOB):
        super().__init__(views, 6, free_intrinsics, use_offsets, loss_scale, shape, shape_frame, lens)
        if len(chain.chain) != self.nv:
            raise ValueError(f"{len(chain.chain)} chain poses for {self.nv} views")
        self.chain = chain
        self.ng = self.n_base + self.N_CHAIN
        self.n_robust = self.n_edge + 2 * self.n_corner
        self.rows_of_view = [np.concatenate([r, self.n_robust + 6 * i + np.arange(6)])
                             for i, r in enumerate(self.rows_of_view)]
        self._RM = Rotation.concatenate([m.rotation for m in chain.chain]).as_matrix() if self.nv else None
        self._tM = np.array([m.translation for m in chain.chain]).reshape(-1, 3)

    def pack_chain(self, intr: np.ndarray, poses: list[np.ndarray], offsets: np.ndarray, xy: np.ndarray,
                   shape: np.ndarray | None = None) -> np.ndarray:
        """x from the intrinsics, the 6-dof poses, offsets and xy = [X rvec, X t, Y rvec, Y t]."""
        base = self.pack(intr, poses, offsets, shape)
        return np.concatenate([base[: self.n_base], np.asarray(xy, float), base[self.n_base:]])

    def chain_params(self, x: np.ndarray) -> np.ndarray:
        return x[self.n_base:self.n_base + self.N_CHAIN]

    def chain_deltas(self, xy: np.ndarray, poses: np.ndarray, chain: list[Any] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Per view the disagreement G_i^-1 G'_i as (rotation vectors (V, 3) rad, translations (V, 3) m);
        ``chain``: other chain poses M_i than the problem's (a perturbed arm). Batched: ``xy`` (B, 12)
        and ``poses`` (B, V, 6) give (B, V, 3) each."""
        xy, poses = np.asarray(xy, float), np.asarray(poses, float)
        batch = xy.shape[:-1]
        nb, nv = int(np.prod(batch)), poses.shape[-2]
        xy = np.repeat(xy.reshape(nb, 1, 12), nv, 1).reshape(-1, 12)
        poses = np.array(np.broadcast_to(poses, (*batch, nv, poses.shape[-1])).reshape(-1, poses.shape[-1]))
        # rotation matrices (one conversion each way; the products by einsum, no BLAS)
        RX, tX = Rotation.from_rotvec(xy[:, 0:3]).as_matrix(), xy[:, 3:6]
        RY, tY = Rotation.from_rotvec(xy[:, 6:9]).as_matrix(), xy[:, 9:12]
        RC, tC = Rotation.from_rotvec(poses[:, :3]).as_matrix(), poses[:, 3:6]
        if chain is None:
            RM, tM = self._RM, self._tM
        else:
            RM = Rotation.concatenate([m.rotation for m in chain]).as_matrix()
            tM = np.array([m.translation for m in chain])
        assert RM is not None
        if nb > 1:
            RM, tM = np.tile(RM, (nb, 1, 1)), np.tile(tM, (nb, 1))

        def apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
            return np.einsum("nij,nj->ni", R, v)

        def mul(A: np.ndarray, B: np.ndarray, transpose_b: bool = False) -> np.ndarray:
            return np.einsum("nij,nkj->nik" if transpose_b else "nij,njk->nik", A, B)

        if self.chain.eye_in_hand:  # M^-1 Y C^-1 X^-1
            RMt = np.transpose(RM, (0, 2, 1))
            R1, t1 = mul(RMt, RY), apply(RMt, tY - tM)
            R2 = mul(R1, RC, True)
            R3 = mul(R2, RX, True)
            t3 = t1 - apply(R2, tC) - apply(R3, tX)
        else:  # M X C Y^-1
            R1, t1 = mul(RM, RX), apply(RM, tX) + tM
            R2, t2 = mul(R1, RC), apply(R1, tC) + t1
            R3 = mul(R2, RY, True)
            t3 = t2 - apply(R3, tY)
        return Rotation.from_matrix(R3).as_rotvec().reshape(*batch, nv, 3), t3.reshape(*batch, nv, 3)

    def chain_residuals(self, xy: np.ndarray, poses: np.ndarray, chain: list[Any] | None = None) -> np.ndarray:
        """(V, 6) normalised chain residuals (rotation then translation), times ``scale`` ((B, V, 6)
        for a batch, :meth:`chain_deltas`)."""
        rv, t = self.chain_deltas(xy, poses, chain)
        c = self.chain
        return np.concatenate([rv / c.sigma_rot, t / c.sigma_trans], -1) * c.scale

    def evaluate(self, x: np.ndarray, intr0: np.ndarray, jac: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, Jg, Jv = super().evaluate(x, intr0, jac)
        _, _, poses, _ = self.unpack(x, intr0)
        xy = self.chain_params(x)
        fp = self.chain_residuals(xy, poses)
        f = np.concatenate([f, fp.ravel()])
        if not jac:
            return f, Jg, Jv
        Jgp, Jvp = self.chain_jacobian(xy, poses)
        return f, np.concatenate([Jg, Jgp]), np.concatenate([Jv, Jvp])

    def chain_jacobian(self, xy: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The chain rows' Jacobian by central differences: (6V, ng) over the global parameters and
        (6V, per_view) over the pose of each row's own view (every perturbation in one batch)."""
        h = 1e-6
        nv = self.nv
        E = h * np.eye(self.N_CHAIN)
        P = h * np.eye(6)[:, None, :]  # pose k of every view moved
        xys = np.concatenate([xy + E, xy - E, np.tile(xy, (12, 1))])
        ps = np.concatenate([np.broadcast_to(poses, (2 * self.N_CHAIN, nv, 6)), poses + P, poses - P])
        r = self.chain_residuals(xys, ps)
        n = self.N_CHAIN
        Jgp = np.zeros((6 * nv, self.ng))
        Jgp[:, self.n_base:self.n_base + n] = ((r[:n] - r[n:2 * n]) / (2 * h)).reshape(n, -1).T
        Jvp = np.zeros((nv, 6, self.per_view))
        Jvp[:, :, :6] = ((r[2 * n:2 * n + 6] - r[2 * n + 6:]) / (2 * h)).transpose(1, 2, 0)
        return Jgp, Jvp.reshape(6 * nv, self.per_view)

    def chain_dense_jacobian(self, xy: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """The chain rows' full Jacobian (6V, parameters)."""
        Jgp, Jvp = self.chain_jacobian(xy, poses)
        J = np.zeros((6 * self.nv, self.ng + self.per_view * self.nv))
        J[:, : self.ng] = Jgp
        for i in range(self.nv):
            s = self.ng + i * self.per_view
            J[6 * i:6 * i + 6, s:s + self.per_view] = Jvp[6 * i:6 * i + 6]
        return J

    def dense_rows(self, Jg: np.ndarray, Jv: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Rows ``rows`` of the full Jacobian (len(rows), parameters) from its blocks (each row's
        own view: edge rows by ``view_of_pt``, corner rows by ``view_of_corner``, chain rows six
        per view)."""
        view = np.concatenate([self.view_of_pt, np.repeat(self.view_of_corner, 2), np.repeat(np.arange(self.nv), 6)])
        J = np.zeros((len(rows), self.ng + self.per_view * self.nv))
        J[:, : self.ng] = Jg[rows]
        cols = self.ng + self.per_view * view[rows][:, None] + np.arange(self.per_view)
        np.put_along_axis(J, cols, Jv[rows], 1)
        return J

    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray:
        w = np.ones(len(f))
        w[: self.n_robust] = super().robust_weights(f[: self.n_robust], loss_scale)
        return w

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float:
        return super().robust_cost(f[: self.n_robust], loss_scale) + 0.5 * float(np.sum(f[self.n_robust:] ** 2))

    def loss_derivatives(self, f: np.ndarray, loss_scale: float) -> tuple[np.ndarray, np.ndarray]:
        psi, dpsi = f.copy(), np.ones(len(f))
        psi[: self.n_robust], dpsi[: self.n_robust] = super().loss_derivatives(f[: self.n_robust], loss_scale)
        return psi, dpsi

    def chain_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Row indices of the chain's rotation rows and translation rows."""
        base = self.n_robust + 6 * np.arange(self.nv)[:, None]
        return (base + np.arange(3)).ravel(), (base + 3 + np.arange(3)).ravel()
