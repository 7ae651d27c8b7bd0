"""Joint nonlinear refinement of intrinsics, plumb_bob distortion, poses, edge offsets and,
optionally, the printed target's shape.

Minimises, with a robust (soft L1) loss, the geometric distance of every subpixel edge point to
the image of its circle, plus the reprojection error of checkerboard corners if any:

- an edge point u is undistorted, its ray is intersected with the plane of its circle, the plane
  point's direction from the circle centre gives the nearest circle point Q (in the plane); the
  residual is the distance of u from the tangent line of the imaged circle at q = proj(Q), signed
  positive on the circle's outer side;
- each view has an edge offset delta (pixels): a dark-inside edge (ring outer, disc) is expected
  at +delta, a dark-outside edge (ring inner) at -delta. Blur seen through a display gamma moves
  the two ring edges in opposite directions by the same amount, so delta is observable and
  absorbs the bias (PAPER.md: 0.02 px of bias moves f by ~0.7 %);
- the target shape (optional, all views share it, as mrcal does for chessboards): the sheet's
  y axis printed at (1 + pitch_ratio) times its nominal scale, and a parabolic out-of-plane warp
  z(x, y) = warp_x (1 - ux^2) + warp_y (1 - uy^2) metres, ux and uy running from -1 to 1 across
  the circles' extent; each circle is moved along the board normal by z at its centre (a circle
  is small against the warp's curvature, so it stays flat).

Poses have 6 dof (rvec, t) or 5 for a target with a single circle centre (rotation about the
ring's axis unobservable). Solved by Levenberg-Marquardt with IRLS weights. The Jacobian is
analytic: at the foot point the residual is r = n . (u - q) with n the unit normal of the imaged
circle, and d r / d theta = -n . dq/d theta (Q slides along the circle, which moves q along the
tangent only, and dn is perpendicular to n while u - q is parallel to it), with dq/d theta the
ordinary projection Jacobian (:func:`project_with_jacobians`). The normal equations are
assembled view by view (each view's parameters touch its rows only).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry.camera import INTRINSIC_BASE, Camera, pixels_to_normalized, project_with_jacobians
from ..geometry.lens import DISTORTION_CHOICES, PLUMB_BOB, LensModel
from .uncertainty import (
    ProjectionUncertainty,
    correlation_factors,
    projection_uncertainty,
    row_variances,
    sandwich_covariance,
)

# the plumb_bob parameter vector (other models: INTRINSIC_BASE + their coefficients)
INTRINSIC_NAMES = INTRINSIC_BASE + PLUMB_BOB.coefficients
SHAPE_NAMES = ("pitch_ratio", "warp_x", "warp_y")
# what a user asks for -> the shape parameters estimated
SHAPE_CHOICES = {"": (), "warp": ("warp_x", "warp_y"), "pitch": ("pitch_ratio",), "all": SHAPE_NAMES}

# what a user asks for -> the distortion coefficients estimated (lens.DISTORTION_CHOICES)
DISTORTION_MODELS = {choice: free for choice, (_, free) in DISTORTION_CHOICES.items()}


def intrinsic_names(lens: LensModel) -> tuple[str, ...]:
    """Names of the intrinsic vector of a lens model: fx fy cx cy skew, then its D."""
    return INTRINSIC_BASE + lens.coefficients


@dataclass
class ViewData:
    """One view's observations in the target's local frame (origin at the first circle centre)."""

    points: np.ndarray  # (N, 2) edge pixels
    centers: np.ndarray  # (N, 2) circle centre of each point, local frame
    radii: np.ndarray  # (N,)
    signs: np.ndarray  # (N,) +1 dark inside, -1 dark outside
    circle_ids: np.ndarray  # (N,) index into Target.circles
    corners: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) pixels
    corner_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) local frame


@dataclass
class RefineResult:
    K: np.ndarray
    D: np.ndarray
    poses: list[np.ndarray]  # per view parameters (5 or 6)
    offsets: np.ndarray  # per view edge offset, px
    std: dict[str, float]  # standard deviation of each free intrinsic
    view_rms: np.ndarray  # per view RMS of edge residuals, px
    view_corner_rms: np.ndarray
    rms: float
    residuals: list[np.ndarray]  # per view edge residuals (signed, px)
    cost: float
    nfev: int
    success: bool
    message: str
    shape: dict[str, float] = field(default_factory=dict)  # SHAPE_NAMES -> value (0 when fixed)
    shape_std: dict[str, float] = field(default_factory=dict)  # estimated shape parameters only
    model: str = "plumb_bob"  # ROS distortion_model of D
    # correlation of the estimated pitch ratio with the aspect ratio fy / fx (a mis-scaled print and non-square pixels
    # look alike unless views are tilted strongly about both axes)
    pitch_aspect_correlation: float = 0.0
    # the solution vector, the problem that defines it and the parameters' covariance (uncertainty.py)
    x: np.ndarray | None = None
    problem: Problem | None = None
    intr0: np.ndarray | None = None
    covariance: np.ndarray | None = None
    kappa: tuple[float, float] = (1.0, 1.0)  # correlation factors of the edge and the corner rows
    corner_residuals: list[np.ndarray] = field(default_factory=list)  # per view (M, 2), observed - predicted

    def camera_of(self, x: np.ndarray) -> Camera:
        """The camera of a parameter vector of :attr:`problem`."""
        assert self.problem is not None and self.intr0 is not None
        K, D = _camera(self.problem.unpack(x, self.intr0)[0])
        return Camera(K, D, 0, 0, self.model)

    def view_poses_of(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R (V, 3, 3), t (V, 3)) of the views for a parameter vector of :attr:`problem`."""
        assert self.problem is not None and self.intr0 is not None
        R, _, t = self.problem.rotations(self.problem.unpack(x, self.intr0)[2])
        return R, t

    def projection_uncertainty(self, width: int, height: int, distance: float | None = None
                               ) -> ProjectionUncertainty:
        """:func:`uncertainty.projection_uncertainty` at ``distance`` (default: the views' median
        target distance)."""
        assert self.x is not None and self.covariance is not None
        if distance is None:
            distance = float(np.median(np.linalg.norm(self.view_poses_of(self.x)[1], axis=1)))
        return projection_uncertainty(self.camera_of, self.view_poses_of, self.x, self.covariance, width, height,
                                      distance)


def rotations_with_jacobians(rvecs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rodrigues for each row of (V, 3): R (V, 3, 3) and dR/drvec (V, 3, 3, 3) indexed [v, k, i, j]."""
    R = np.empty((len(rvecs), 3, 3))
    dR = np.empty((len(rvecs), 3, 3, 3))
    for i, rv in enumerate(rvecs):
        Ri, jac = cv2.Rodrigues(np.ascontiguousarray(rv, dtype=np.float64).reshape(3, 1))
        R[i] = Ri
        dR[i] = jac.reshape(3, 3, 3)
    return R, dR


def shape_frame_of(points: np.ndarray) -> tuple[float, float, float, float]:
    """(x mid, y mid, x half-width, y half-width) of a point set: the frame of the warp."""
    lo, hi = points.min(0), points.max(0)
    half = np.maximum((hi - lo) / 2, 1e-3)
    return float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2), float(half[0]), float(half[1])


class Problem:
    """Parameter layout, residuals and Jacobian of one refinement.

    x = [free intrinsics, estimated shape parameters, view 0 (pose, offset), view 1, ...]."""

    def __init__(self, views: list[ViewData], dof: int, free_intrinsics: tuple[str, ...], use_offsets: bool,
                 loss_scale: float = 0.3, shape: tuple[str, ...] = (),
                 shape_frame: tuple[float, float, float, float] | None = None, lens: LensModel = PLUMB_BOB):
        self.views = views
        self.lens = lens
        self.names = intrinsic_names(lens)
        self.dof = dof
        self.use_offsets = use_offsets
        self.free = [self.names.index(n) for n in free_intrinsics]
        self.shape_idx = [SHAPE_NAMES.index(n) for n in shape]
        # globals: free intrinsics, shape parameters, then (subclasses) further global parameters
        self.n_base = len(self.free) + len(self.shape_idx)
        self.ng = self.n_base
        self.nv = len(views)
        self.per_view = dof + (1 if use_offsets else 0)
        self.loss_scale = loss_scale
        self.pts = np.concatenate([v.points for v in views])
        self.centers = np.concatenate([v.centers for v in views])
        self.radii = np.concatenate([v.radii for v in views])
        self.signs = np.concatenate([v.signs for v in views]).astype(float)
        self.view_of_pt = np.concatenate([np.full(len(v.points), i) for i, v in enumerate(views)])
        self.corners = np.concatenate([v.corners for v in views]) if views else np.zeros((0, 2))
        self.corner_obj = np.concatenate([v.corner_obj for v in views]) if views else np.zeros((0, 2))
        self.view_of_corner = np.concatenate([np.full(len(v.corners), i) for i, v in enumerate(views)])
        self.n_edge = len(self.pts)
        bounds = np.concatenate([[0], np.cumsum([len(v.points) for v in views])])
        self.edge_slices = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
        self.n_corner = len(self.corners)
        self.frame = shape_frame or shape_frame_of(np.concatenate([self.centers, self.corner_obj]))
        rows = np.concatenate([self.view_of_pt, np.repeat(self.view_of_corner, 2)])
        self.rows_of_view = [np.flatnonzero(rows == i) for i in range(self.nv)]

    # -- parameter packing -------------------------------------------------------------
    def pack(self, intr: np.ndarray, poses: list[np.ndarray], offsets: np.ndarray,
             shape: np.ndarray | None = None) -> np.ndarray:
        shape = np.zeros(len(SHAPE_NAMES)) if shape is None else np.asarray(shape, float)
        per = [np.concatenate([p, [o]]) if self.use_offsets else p for p, o in zip(poses, offsets, strict=True)]
        return np.concatenate([intr[self.free], shape[self.shape_idx], *per])

    def unpack(self, x: np.ndarray, intr0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """-> (all intrinsics, all 3 shape parameters, poses (V, dof), offsets (V,))."""
        intr = intr0.copy()
        nf = len(self.free)
        intr[self.free] = x[:nf]
        shape = np.zeros(len(SHAPE_NAMES))
        shape[self.shape_idx] = x[nf:self.n_base]
        vp = x[self.ng:].reshape(self.nv, self.per_view)
        poses = vp[:, : self.dof]
        offsets = vp[:, self.dof] if self.use_offsets else np.zeros(self.nv)
        return intr, shape, poses, offsets

    def rotations(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """R (V, 3, 3), dR/d(pose rotation parameters) (V, dof - 3, 3, 3), t (V, 3)."""
        if self.dof == 6:
            rv, t = poses[:, :3], poses[:, 3:6]
        else:
            rv = np.concatenate([poses[:, :2], np.zeros((len(poses), 1))], 1)
            t = poses[:, 2:5]
        R, dR = rotations_with_jacobians(rv)
        return R, dR[:, : self.dof - 3], t

    def board(self, xy: np.ndarray, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nominal local points (N, 2) -> printed points (N, 3) = (x, (1 + pitch_ratio) y, z(x, y)),
        d printed / d shape (N, 3, 3), and the surface slope (dz/dx, dz/dy) (N, 2)."""
        rho, wx, wy = shape
        xm, ym, xh, yh = self.frame
        ux, uy = (xy[:, 0] - xm) / xh, (xy[:, 1] - ym) / yh
        bx, by = 1 - ux * ux, 1 - uy * uy
        out = np.stack([xy[:, 0], xy[:, 1] * (1 + rho), wx * bx + wy * by], 1)
        dP = np.zeros((len(xy), 3, 3))
        dP[:, 1, 0] = xy[:, 1]
        dP[:, 2, 1], dP[:, 2, 2] = bx, by
        slope = np.stack([-2 * wx * ux / xh, -2 * wy * uy / yh], 1)
        return out, dP, slope

    # -- residuals and Jacobian ------------------------------------------------------------
    def evaluate(self, x: np.ndarray, intr0: np.ndarray, jac: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals f (rows), and if ``jac``: dF/d globals (rows, ng) and dF/d own view block
        (rows, per_view); rows are the edge points, then x and y of every corner."""
        intr, shape, poses, offsets = self.unpack(x, intr0)
        K, D = _camera(intr)
        R, dR, t = self.rotations(poses)
        if self.n_edge:
            f, Jg, Jv = self._edges(K, D, R, dR, t, shape, offsets, jac)
        else:  # checkerboard corners only
            f, Jg, Jv = np.zeros(0), np.zeros((0, self.ng)), np.zeros((0, self.per_view))
        if self.n_corner:
            fc, Jgc, Jvc = self._corners(K, D, R, dR, t, shape, jac)
            f = np.concatenate([f, fc])
            if jac:
                Jg, Jv = np.concatenate([Jg, Jgc]), np.concatenate([Jv, Jvc])
        bad = ~np.isfinite(f)
        if bad.any():
            f = np.where(bad, 1e3, f)
            if jac:
                Jg[bad], Jv[bad] = 0.0, 0.0
        return f, Jg, Jv

    def residuals(self, x: np.ndarray, intr0: np.ndarray) -> np.ndarray:
        return self.evaluate(x, intr0, jac=False)[0]

    # -- loss (every row robust here; subclasses may add rows with a quadratic loss) --------
    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray:
        """IRLS weights of the soft-L1 loss, 1 / sqrt(1 + (r / f)^2)."""
        return 1.0 / np.sqrt(1 + (f / loss_scale) ** 2)

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float:
        """Soft-L1 cost f^2 sum (sqrt(1 + (r / f)^2) - 1)."""
        z = (f / loss_scale) ** 2
        return float(loss_scale**2 * np.sum(np.sqrt(1 + z) - 1))

    def _per_view(self, A: np.ndarray, M: np.ndarray) -> np.ndarray:
        """Rows of A (n, ..., 3) times their view's matrix M[v] (3, k): one product per view (the
        edge rows of a view are contiguous)."""
        out = np.empty((*A.shape[:-1], M.shape[-1]))
        for v, sl in enumerate(self.edge_slices):
            out[sl] = A[sl] @ M[v]
        return out

    def _edges(self, K: np.ndarray, D: np.ndarray, R: np.ndarray, dR: np.ndarray, t: np.ndarray,
               shape: np.ndarray, offsets: np.ndarray, jac: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        vi = self.view_of_pt
        Rt = np.transpose(R, (0, 2, 1))
        tv = t[vi]
        ctr = self.board(self.centers, shape)[0]
        rays = self.lens.undistort(pixels_to_normalized(self.pts, K), D, strict=False)
        n = R[:, :, 2][vi]
        lam = (np.sum(n * tv, 1) + ctr[:, 2]) / np.sum(n * rays, 1)
        X = rays * lam[:, None]
        P = self._per_view(X - tv, R)  # R^T (X - t), as rows
        rel = P[:, :2] - ctr[:, :2]
        rho = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        u = rel / rho[:, None]
        r = self.radii[:, None]
        s1 = 1 + shape[0]
        for step in range(2):
            # the circle point at angle u, drawn on the printed sheet (each point at its own z)
            Q, dPds, slope = self.board(self.centers + r * u, shape)
            q, dqdX, dqdI = project_with_jacobians(self._per_view(Q, Rt) + tv, K, D, self.lens)
            dqdP = self._per_view(dqdX, R)  # image motion per board-frame motion
            tang = np.stack([-u[:, 1], s1 * u[:, 0], slope[:, 0] * -u[:, 1] + slope[:, 1] * u[:, 0]], 1)
            ti = np.einsum("nij,nj->ni", dqdP, tang)  # image of the circle's tangent (per radian / r)
            if step:
                break
            # slide Q along the circle to the image foot point of u (one Gauss-Newton step on the
            # angle): the radial point of the plane is not the nearest in a perspective image, and
            # the Jacobian below is exact only at the foot point
            dq = ti * r
            dth = np.sum(dq * (self.pts - q), 1) / np.maximum(np.sum(dq * dq, 1), 1e-30)
            c, s_ = np.cos(dth), np.sin(dth)
            u = np.stack([c * u[:, 0] - s_ * u[:, 1], s_ * u[:, 0] + c * u[:, 1]], 1)
        radial = np.stack([u[:, 0], s1 * u[:, 1], slope[:, 0] * u[:, 0] + slope[:, 1] * u[:, 1]], 1)
        ri = np.einsum("nij,nj->ni", dqdP, radial)  # image of the outward radius
        ti /= np.maximum(np.hypot(ti[:, 0], ti[:, 1]), 1e-15)[:, None]
        orient = np.sign(ri[:, 0] * ti[:, 1] - ri[:, 1] * ti[:, 0])
        nrm = np.stack([ti[:, 1], -ti[:, 0]], 1) * orient[:, None]  # outward unit normal in the image
        f = np.sum(nrm * (self.pts - q), 1) - self.signs * offsets[vi]
        if not jac:
            return f, np.zeros((0, self.ng)), np.zeros((0, self.per_view))
        h = np.einsum("ni,nij->nj", nrm, dqdX)  # n^T dq/dX
        Jg = np.zeros((len(f), self.ng))
        nf = len(self.free)
        Jg[:, :nf] = -np.einsum("ni,nij->nj", nrm, dqdI[:, :, self.free])
        if self.shape_idx:
            g = self._per_view(h, R)  # n^T dq/dP
            Jg[:, nf:self.n_base] = -np.einsum("nk,nks->ns", g, dPds[:, :, self.shape_idx])
        Jv = np.empty((len(f), self.per_view))
        # n^T dq/dX . (dR/drv_k Q): the outer product h Q^T against each view's dR/drv_k
        nr = self.dof - 3
        Jv[:, :nr] = -self._per_view((h[:, :, None] * Q[:, None, :]).reshape(-1, 1, 9),
                                     dR.reshape(len(dR), nr, 9).transpose(0, 2, 1))[:, 0, :]
        Jv[:, self.dof - 3: self.dof] = -h
        if self.use_offsets:
            Jv[:, self.dof] = -self.signs
        return f, Jg, Jv

    def _corners(self, K: np.ndarray, D: np.ndarray, R: np.ndarray, dR: np.ndarray, t: np.ndarray,
                 shape: np.ndarray, jac: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        vi = self.view_of_corner
        P, dPds, _ = self.board(self.corner_obj, shape)
        Rv = R[vi]
        q, dqdX, dqdI = project_with_jacobians(np.einsum("nij,nj->ni", Rv, P) + t[vi], K, D, self.lens)
        f = (q - self.corners).ravel()
        if not jac:
            return f, np.zeros((0, self.ng)), np.zeros((0, self.per_view))
        m = len(q)
        nf = len(self.free)
        Jg = np.zeros((m, 2, self.ng))
        Jg[:, :, :nf] = dqdI[:, :, self.free]
        if self.shape_idx:
            dqdP = np.einsum("nij,njk->nik", dqdX, Rv)
            Jg[:, :, nf:self.n_base] = np.einsum("nik,nks->nis", dqdP, dPds[:, :, self.shape_idx])
        Jv = np.zeros((m, 2, self.per_view))
        Jv[:, :, : self.dof - 3] = np.einsum("nij,nkjl,nl->nik", dqdX, dR[vi], P)
        Jv[:, :, self.dof - 3: self.dof] = dqdX
        return f, Jg.reshape(2 * m, self.ng), Jv.reshape(2 * m, self.per_view)

    def normal_equations(self, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray, w: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """A = J^T W J and g = J^T W f, assembled from the block structure of J."""
        ng, pv = self.ng, self.per_view
        size = ng + pv * self.nv
        A = np.zeros((size, size))
        g = np.zeros(size)
        Jgw = Jg * w[:, None]
        A[:ng, :ng] = Jg.T @ Jgw
        g[:ng] = Jgw.T @ f
        for i, rows in enumerate(self.rows_of_view):
            s = ng + i * pv
            Jvi = Jv[rows]
            Jviw = Jvi * w[rows, None]
            A[s:s + pv, s:s + pv] = Jvi.T @ Jviw
            A[:ng, s:s + pv] = Jg[rows].T @ Jviw
            A[s:s + pv, :ng] = A[:ng, s:s + pv].T
            g[s:s + pv] = Jviw.T @ f[rows]
        return A, g

    def dense_jacobian(self, Jg: np.ndarray, Jv: np.ndarray) -> np.ndarray:
        """The full Jacobian (rows, parameters), for tests and small problems."""
        J = np.zeros((len(Jg), self.ng + self.per_view * self.nv))
        J[:, : self.ng] = Jg
        for i, rows in enumerate(self.rows_of_view):
            s = self.ng + i * self.per_view
            J[rows, s:s + self.per_view] = Jv[rows]
        return J


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
        self._RM = Rotation.concatenate([m.rotation for m in chain.chain]) if self.nv else None
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
        ``chain``: other chain poses M_i than the problem's (a perturbed arm)."""
        RX, tX = Rotation.from_rotvec(xy[0:3]), xy[3:6]
        RY, tY = Rotation.from_rotvec(xy[6:9]), xy[9:12]
        RC, tC = Rotation.from_rotvec(poses[:, :3]), poses[:, 3:6]
        if chain is None:
            RM, tM = self._RM, self._tM
        else:
            RM, tM = Rotation.concatenate([m.rotation for m in chain]), np.array([m.translation for m in chain])
        assert RM is not None
        if self.chain.eye_in_hand:  # M^-1 Y C^-1 X^-1
            RMi = RM.inv()
            R1, t1 = RMi * RY, RMi.apply(tY - tM)
            RCi = RC.inv()
            R2, t2 = R1 * RCi, t1 - (R1 * RCi).apply(tC)
            RXi = RX.inv()
            R3, t3 = R2 * RXi, t2 - (R2 * RXi).apply(tX)
        else:  # M X C Y^-1
            R1, t1 = RM * RX, RM.apply(tX) + tM
            R2, t2 = R1 * RC, R1.apply(tC) + t1
            RYi = RY.inv()
            R3, t3 = R2 * RYi, t2 - (R2 * RYi).apply(tY)
        return R3.as_rotvec().reshape(-1, 3), np.asarray(t3).reshape(-1, 3)

    def chain_residuals(self, xy: np.ndarray, poses: np.ndarray, chain: list[Any] | None = None) -> np.ndarray:
        """(V, 6) normalised chain residuals (rotation then translation), times ``scale``."""
        rv, t = self.chain_deltas(xy, poses, chain)
        c = self.chain
        return np.concatenate([rv / c.sigma_rot, t / c.sigma_trans], 1) * c.scale

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
        (6V, per_view) over the pose of each row's own view."""
        h = 1e-6
        nv = self.nv
        Jgp = np.zeros((6 * nv, self.ng))
        for k in range(self.N_CHAIN):
            e = np.zeros(self.N_CHAIN)
            e[k] = h
            d = (self.chain_residuals(xy + e, poses) - self.chain_residuals(xy - e, poses)) / (2 * h)
            Jgp[:, self.n_base + k] = d.ravel()
        Jvp = np.zeros((nv, 6, self.per_view))
        for k in range(6):
            e = np.zeros(6)
            e[k] = h
            Jvp[:, :, k] = (self.chain_residuals(xy, poses + e) - self.chain_residuals(xy, poses - e)) / (2 * h)
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

    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray:
        w = np.ones(len(f))
        w[: self.n_robust] = super().robust_weights(f[: self.n_robust], loss_scale)
        return w

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float:
        return super().robust_cost(f[: self.n_robust], loss_scale) + 0.5 * float(np.sum(f[self.n_robust:] ** 2))

    def chain_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Row indices of the chain's rotation rows and translation rows."""
        base = self.n_robust + 6 * np.arange(self.nv)[:, None]
        return (base + np.arange(3)).ravel(), (base + 3 + np.arange(3)).ravel()


def _camera(intr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    return K, intr[5:].copy()


class LeastSquaresProblem(Protocol):
    """What :func:`levenberg_marquardt` and the sandwich covariance need of a problem:
    :class:`Problem`, :class:`ChainProblem`, :class:`~.rig_problem.RigProblem`."""

    def evaluate(self, x: np.ndarray, intr0: np.ndarray, jac: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray: ...

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float: ...

    def normal_equations(self, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray, w: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class LMResult:
    x: np.ndarray
    fun: np.ndarray
    normal_matrix: np.ndarray  # J^T W J at the solution
    weights: np.ndarray
    cost: float
    nfev: int
    iterations: int
    success: bool
    message: str


def levenberg_marquardt(prob: LeastSquaresProblem, x0: np.ndarray, intr0: np.ndarray, loss_scale: float,
                        max_iter: int = 60, tol: float = 1e-10) -> LMResult:
    """Levenberg-Marquardt with iteratively reweighted soft-L1 loss rho(z) = 2 (sqrt(1 + z) - 1),
    z = (r / f)^2, weights 1 / sqrt(1 + z); normal equations from :meth:`Problem.normal_equations`
    (Jacobi-scaled, dense: a few hundred parameters at most)."""
    x = x0.copy()
    f, Jg, Jv = prob.evaluate(x, intr0)
    nfev = 1

    def robust_cost(r: np.ndarray) -> float:
        return prob.robust_cost(r, loss_scale)

    cost = robust_cost(f)
    lam = 1e-3
    message, success = "maximum iterations reached", False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        w = prob.robust_weights(f, loss_scale)
        A, g = prob.normal_equations(f, Jg, Jv, w)
        d = np.sqrt(np.maximum(np.diag(A), 1e-30))
        An = A / d[:, None] / d[None, :]
        gn = g / d
        improved = False
        for _ in range(12):
            try:
                step = -np.linalg.solve(An + lam * np.eye(len(x)), gn) / d
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            xn = x + step
            fn, Jgn, Jvn = prob.evaluate(xn, intr0)
            nfev += 1
            cn = robust_cost(fn)
            if cn < cost:
                rel = (cost - cn) / max(cost, 1e-300)
                x, f, Jg, Jv, cost = xn, fn, Jgn, Jvn, cn
                lam = max(lam * 0.2, 1e-9)
                improved = True
                break
            lam *= 10
        if not improved:
            message, success = "no further decrease of the cost", True
            break
        if rel < tol or np.linalg.norm(step * d) < tol * (np.linalg.norm(x * d) + tol):
            message, success = "converged", True
            break
    w = prob.robust_weights(f, loss_scale)
    A, _ = prob.normal_equations(f, Jg, Jv, w)
    return LMResult(x, f, A, w, cost, nfev, it, success, message)


def refine(views: list[ViewData], K0: np.ndarray, D0: np.ndarray, poses0: list[np.ndarray], dof: int,
           distortion: str = "plumb_bob", zero_skew: bool = True, use_offsets: bool = True,
           loss_scale: float = 0.3, max_iter: int = 60, shape: tuple[str, ...] = (),
           shape_frame: tuple[float, float, float, float] | None = None) -> RefineResult:
    """Least squares over K, D, poses, offsets and the named shape parameters (module docstring).

    ``shape_frame`` is (x mid, y mid, x half-width, y half-width) of the warp in the local frame
    (default: the extent of the observed circles); the shape starts flat and true to scale, and
    shape parameters not named stay so."""
    if distortion not in DISTORTION_CHOICES:
        raise ValueError(f"unknown distortion model {distortion!r}: {', '.join(DISTORTION_CHOICES)}")
    lens, free_d = DISTORTION_CHOICES[distortion]
    names = intrinsic_names(lens)
    unknown = [s for s in shape if s not in SHAPE_NAMES]
    if unknown:
        raise ValueError(f"unknown target shape parameter(s) {unknown}: choose from {', '.join(SHAPE_NAMES)}")
    free = ("fx", "fy", "cx", "cy") + (() if zero_skew else ("skew",)) + free_d
    prob = Problem(views, dof, free, use_offsets, loss_scale, tuple(shape), shape_frame, lens)
    D0 = np.asarray(D0, float).reshape(-1)
    if len(D0) != lens.n:
        raise ValueError(f"start D has {len(D0)} coefficients; {lens.name} has {lens.n}")
    intr0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], 0.0 if zero_skew else K0[0, 1], *D0])
    for name in names[5:]:
        if name not in free:  # coefficients the model does not estimate are held at zero
            intr0[names.index(name)] = 0.0
    x0 = prob.pack(intr0, poses0, np.zeros(len(views)))
    sol = levenberg_marquardt(prob, x0, intr0, loss_scale, max_iter=max_iter)
    intr_, shape_v, poses, offsets = prob.unpack(sol.x, intr0)
    K, D = _camera(intr_)
    R, dR, t = prob.rotations(poses)
    er = prob._edges(K, D, R, dR, t, shape_v, offsets, jac=False)[0]
    per_view = [er[prob.view_of_pt == i] for i in range(len(views))]
    view_rms = np.array([np.sqrt(np.mean(r * r)) if len(r) else 0.0 for r in per_view])
    corner_rms = np.zeros(len(views))
    corner_res = [np.zeros((0, 2)) for _ in views]
    if prob.n_corner:
        cr = -prob._corners(K, D, R, dR, t, shape_v, jac=False)[0].reshape(-1, 2)  # observed - predicted
        for i in range(len(views)):
            sel = prob.view_of_corner == i
            if sel.any():
                corner_res[i] = cr[sel]
                corner_rms[i] = float(np.sqrt(np.mean(np.sum(cr[sel] ** 2, 1))))
    # standard deviations from the sandwich covariance with correlated, per-view noise (uncertainty.py)
    std: dict[str, float] = {}
    shape_std: dict[str, float] = {}
    corr = 0.0
    cov: np.ndarray | None = None
    kappa = correlation_factors(prob, views, sol.fun)
    try:
        _, Jg, Jv = prob.evaluate(sol.x, intr0)
        var = row_variances(prob, views, sol.fun, sol.weights, len(sol.x))
        cov = sandwich_covariance(prob, sol.normal_matrix, sol.fun, Jg, Jv, sol.weights, var)
        for k, idx in enumerate(prob.free):
            std[names[idx]] = float(np.sqrt(max(cov[k, k], 0.0)))
        for k, idx in enumerate(prob.shape_idx):
            j = len(prob.free) + k
            shape_std[SHAPE_NAMES[idx]] = float(np.sqrt(max(cov[j, j], 0.0)))
            if SHAPE_NAMES[idx] == "pitch_ratio" and {0, 1} <= set(prob.free):
                g = np.zeros(len(cov))  # d(fy - a fx): the aspect ratio a = fy / fx, linearised
                g[prob.free.index(1)], g[prob.free.index(0)] = 1.0, -K[1, 1] / K[0, 0]
                corr = float(cov[j] @ g / np.sqrt(max(cov[j, j] * (g @ cov @ g), 1e-300)))
    except np.linalg.LinAlgError:
        pass
    return RefineResult(K, D, [p.copy() for p in poses], offsets, std, view_rms, corner_rms,
                        float(np.sqrt(np.mean(er * er))), per_view, float(sol.cost), int(sol.nfev),
                        bool(sol.success), str(sol.message), dict(zip(SHAPE_NAMES, map(float, shape_v), strict=True)),
                        shape_std, lens.name, float(corr), sol.x, prob, intr0, cov, kappa, corner_res)
