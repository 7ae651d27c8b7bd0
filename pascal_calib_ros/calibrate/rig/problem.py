"""The joint problem of a camera rig: every camera's intrinsics and lens model, every camera's
pose in camera 0's frame, one target pose per shot, one edge offset per view.

Frames: the rig's frame is camera 0's. Camera c's *extrinsic* E_c maps camera 0's frame into its
own, X_c = R_c X_0 + t_c (for a stereo pair: OpenCV's ``stereoCalibrate`` R, T,
X_right = R X_left + T); E_0 is the identity and not estimated. Shot s has one target pose S_s
(target's local frame -> camera 0). The view of shot s by camera c then has the pose
C_cs = E_c S_s (R_c R_s, R_c t_s + t_c): mrcal's and Kalibr's structure (one pose per shot, one
transform per camera), so that every view of a shot agrees on where the target was.

The residuals are those of :class:`~.refine.Problem` (edge points against the image of their
circle, checkerboard corners), one Problem per camera over the views it has; nothing of that
model is written twice. A Problem's Jacobian over a view's pose (phi_cs, t_cs) is chained to the
rig's parameters with the composition's Jacobians (:func:`~..geometry.so3.compose_with_jacobians`):
d f / d E_c = d f / d C_cs . d C_cs / d E_c (a global column block) and
d f / d S_s = d f / d C_cs . d C_cs / d S_s (the shot's own block). The normal equations are
assembled shot by shot: a shot's block holds its pose and the edge offsets of its views.

x = [camera 0's free intrinsics, camera 1's, ..., E_1 (phi, t), ..., E_{N-1},
     shot 0 (pose, offset of each of its views), shot 1, ...].
"""

from __future__ import annotations

import numpy as np

from ...geometry import compose_with_jacobians
from ..solver.problem import Problem


class RigProblem:
    """Parameter layout, residuals and Jacobian of the joint rig refinement (module docstring).

    ``subs[c]`` is camera c's :class:`~.refine.Problem` (6-dof view poses) over its views,
    ``view_shot[c][j]`` the shot of its view j. ``evaluate`` takes the cameras' start intrinsics
    (``intr0`` of each Problem) concatenated."""

    def __init__(self, subs: list[Problem], view_shot: list[np.ndarray], n_shots: int):
        if any(s.dof != 6 for s in subs):
            raise ValueError("the cameras' problems must have 6-dof view poses")
        self.subs = subs
        self.n_cam = len(subs)
        self.view_shot = [np.asarray(v, int) for v in view_shot]
        self.n_shots = n_shots
        self.dof = 6
        self.use_offsets = subs[0].use_offsets
        nf = [len(s.free) for s in subs]
        self.intr_start = np.concatenate([[0], np.cumsum(nf)]).astype(int)
        self.rig_start = int(self.intr_start[-1])
        self.ng = self.rig_start + 6 * (self.n_cam - 1)
        self.intr_len = [len(s.names) for s in subs]  # full intrinsic vector per camera (intr0)
        # rows: camera 0's, then camera 1's, ...; the views of each shot with their offset slot
        self.row_start = np.concatenate([[0], np.cumsum([s.n_edge + 2 * s.n_corner for s in subs])]).astype(int)
        self.views_of_shot: list[list[tuple[int, int]]] = [[] for _ in range(n_shots)]
        for c, vs in enumerate(self.view_shot):
            for j, s in enumerate(vs):
                self.views_of_shot[s].append((c, j))
        per_off = 1 if self.use_offsets else 0
        sizes = [self.dof + per_off * len(v) for v in self.views_of_shot]
        self.block_start = self.ng + np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.size = int(self.block_start[-1])
        self.rows_of_shot: list[np.ndarray] = []
        self.slot_of_row: list[np.ndarray] = []
        for views in self.views_of_shot:
            rows = [self.row_start[c] + self.subs[c].rows_of_view[j] for c, j in views]
            self.rows_of_shot.append(np.concatenate(rows).astype(int) if rows else np.zeros(0, int))
            self.slot_of_row.append(np.repeat(np.arange(len(views)), [len(r) for r in rows]).astype(int))

    # -- parameter packing -------------------------------------------------------------
    def pack(self, intr: list[np.ndarray], extrinsics: np.ndarray, shots: np.ndarray,
             offsets: list[np.ndarray] | None = None) -> np.ndarray:
        """x from each camera's full intrinsic vector, the extrinsics (N, 6) (phi, t; row 0
        ignored), the shot poses (S, 6) (phi, t) and each camera's view offsets (zero if None)."""
        x = np.zeros(self.size)
        for c, sub in enumerate(self.subs):
            x[self.intr_start[c]:self.intr_start[c + 1]] = np.asarray(intr[c], float)[sub.free]
        x[self.rig_start:self.ng] = np.asarray(extrinsics, float)[1:].ravel()
        for s, views in enumerate(self.views_of_shot):
            b = self.block_start[s]
            x[b:b + self.dof] = shots[s]
            if self.use_offsets:
                for k, (c, j) in enumerate(views):
                    x[b + self.dof + k] = 0.0 if offsets is None else offsets[c][j]
        return x

    def unpack(self, x: np.ndarray, intr0: np.ndarray
               ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, list[np.ndarray]]:
        """-> (each camera's full intrinsics, extrinsics (N, 6) with row 0 zero, shot poses
        (S, 6), each camera's view offsets)."""
        intr, start = [], 0
        for c, sub in enumerate(self.subs):
            v = np.asarray(intr0[start:start + self.intr_len[c]], float).copy()
            v[sub.free] = x[self.intr_start[c]:self.intr_start[c + 1]]
            intr.append(v)
            start += self.intr_len[c]
        ext = np.zeros((self.n_cam, 6))
        ext[1:] = x[self.rig_start:self.ng].reshape(-1, 6)
        shots = np.array([x[b:b + self.dof] for b in self.block_start[:-1]]).reshape(self.n_shots, self.dof)
        offsets = [np.zeros(len(v)) for v in self.view_shot]
        if self.use_offsets:
            for s, views in enumerate(self.views_of_shot):
                for k, (c, j) in enumerate(views):
                    offsets[c][j] = x[self.block_start[s] + self.dof + k]
        return intr, ext, shots, offsets

    def view_poses(self, c: int, ext: np.ndarray, shots: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Camera c's view poses (phi (V, 3), t (V, 3)) and d(phi, t)/dE_c, d(phi, t)/dS (V, 6, 6)."""
        sel = shots[self.view_shot[c]]
        rv_s, t_s = sel[:, :3], sel[:, 3:]
        n = len(rv_s)
        return compose_with_jacobians(np.tile(ext[c, :3], (n, 1)), np.tile(ext[c, 3:], (n, 1)), rv_s, t_s)

    def sub_vector(self, c: int, x: np.ndarray, ext: np.ndarray, shots: np.ndarray, offsets: list[np.ndarray]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Camera c's Problem vector at x, with the composition's Jacobians (see view_poses)."""
        rv, t, Da, Db = self.view_poses(c, ext, shots)
        per = np.c_[rv, t, offsets[c]] if self.use_offsets else np.c_[rv, t]
        return np.concatenate([x[self.intr_start[c]:self.intr_start[c + 1]], per.ravel()]), Da, Db

    # -- residuals and Jacobian ------------------------------------------------------------
    def evaluate(self, x: np.ndarray, intr0: np.ndarray, jac: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals (every camera's rows, camera by camera), and if ``jac``: d f / d globals
        (rows, ng) and d f / d the row's shot block as (rows, 7): the shot pose's columns,
        then the row's own view offset (placed in its slot by :meth:`normal_equations`)."""
        intr, ext, shots, offsets = self.unpack(x, intr0)
        n_rows = int(self.row_start[-1])
        f = np.zeros(n_rows)
        Jg = np.zeros((n_rows, self.ng)) if jac else np.zeros((0, self.ng))
        Jv = np.zeros((n_rows, self.dof + 1)) if jac else np.zeros((0, self.dof + 1))
        for c, sub in enumerate(self.subs):
            xc, Da, Db = self.sub_vector(c, x, ext, shots, offsets)
            fc, Jgc, Jvc = sub.evaluate(xc, intr[c], jac)
            r0 = self.row_start[c]
            f[r0:r0 + len(fc)] = fc
            if not jac:
                continue
            Jg[r0:r0 + len(fc), self.intr_start[c]:self.intr_start[c + 1]] = Jgc
            rig = slice(self.rig_start + 6 * (c - 1), self.rig_start + 6 * c)
            for j, rows in enumerate(sub.rows_of_view):
                Jp = Jvc[rows, :6]
                if c:
                    Jg[r0 + rows, rig] = Jp @ Da[j]
                Jv[r0 + rows, :self.dof] = Jp @ Db[j]
                if self.use_offsets:
                    Jv[r0 + rows, self.dof] = Jvc[rows, 6]
        return f, Jg, Jv

    def residuals(self, x: np.ndarray, intr0: np.ndarray) -> np.ndarray:
        return self.evaluate(x, intr0, jac=False)[0]

    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray:
        """The cameras' soft-L1 IRLS weights (:meth:`~.refine.Problem.robust_weights`)."""
        return self.subs[0].robust_weights(f, loss_scale)

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float:
        return self.subs[0].robust_cost(f, loss_scale)

    def loss_derivatives(self, f: np.ndarray, loss_scale: float) -> tuple[np.ndarray, np.ndarray]:
        """(psi, psi') of the cameras' loss (:meth:`~.problem.Problem.loss_derivatives`)."""
        return self.subs[0].loss_derivatives(f, loss_scale)

    def shot_jacobian(self, s: int, Jv: np.ndarray) -> np.ndarray:
        """Shot s's rows of the Jacobian over its block (pose, then one offset per view)."""
        rows = self.rows_of_shot[s]
        Jb = np.zeros((len(rows), int(self.block_start[s + 1] - self.block_start[s])))
        Jb[:, :self.dof] = Jv[rows, :self.dof]
        if self.use_offsets:
            Jb[np.arange(len(rows)), self.dof + self.slot_of_row[s]] = Jv[rows, self.dof]
        return Jb

    def normal_equations(self, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray, w: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """A = J^T W J and g = J^T W f, assembled shot by shot."""
        ng = self.ng
        A = np.zeros((self.size, self.size))
        g = np.zeros(self.size)
        Jgw = Jg * w[:, None]
        A[:ng, :ng] = Jg.T @ Jgw
        g[:ng] = Jgw.T @ f
        for s, rows in enumerate(self.rows_of_shot):
            a, b = self.block_start[s], self.block_start[s + 1]
            Jb = self.shot_jacobian(s, Jv)
            Jbw = Jb * w[rows, None]
            A[a:b, a:b] = Jb.T @ Jbw
            A[:ng, a:b] = Jg[rows].T @ Jbw
            A[a:b, :ng] = A[:ng, a:b].T
            g[a:b] = Jbw.T @ f[rows]
        return A, g

    def dense_jacobian(self, Jg: np.ndarray, Jv: np.ndarray) -> np.ndarray:
        """The full Jacobian (rows, parameters), for tests."""
        J = np.zeros((len(Jg), self.size))
        J[:, :self.ng] = Jg
        for s, rows in enumerate(self.rows_of_shot):
            J[rows, self.block_start[s]:self.block_start[s + 1]] = self.shot_jacobian(s, Jv)
        return J

    def camera_rows(self, c: int) -> slice:
        """Camera c's rows in the stacked residuals."""
        return slice(int(self.row_start[c]), int(self.row_start[c + 1]))
