"""The refinement's problem: parameter layout, residuals and analytic Jacobian of intrinsics, lens
model, poses, edge offsets and, optionally, the printed target's shape.

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
from dataclasses import dataclass

import cv2
import numpy as np

from ...geometry import (
    DISTORTION_CHOICES,
    INTRINSIC_BASE,
    PLUMB_BOB,
    LensModel,
    PolynomialModel,
    pixels_to_normalized,
    project_with_jacobians,
    project_with_point_jacobian,
)
from .observations import ViewData

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


@dataclass(frozen=True)
class EdgeFit:
    """The edge rows at one parameter vector: residuals, and what their Jacobian needs (per point
    the outward unit normal in the image, the foot point on the printed sheet (x, y on a flat one)
    and in the camera frame, dq/dX there, d printed point / d shape)."""

    f: np.ndarray
    nrm: np.ndarray
    Q: np.ndarray
    Xc: np.ndarray
    dqdX: np.ndarray
    dPds: np.ndarray


def _times(J: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rows of J (N, 2, 3) times the vectors v (N, 3): (N, 2)."""
    return J[:, :, 0] * v[:, 0, None] + J[:, :, 1] * v[:, 1, None] + J[:, :, 2] * v[:, 2, None]


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
        self._ray_cache: tuple[bytes, np.ndarray] | None = None
        self._fit_cache: tuple[bytes, EdgeFit] | None = None
        self._order_cache: tuple[int, np.ndarray | None, list[int]] | None = None

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
        (rows, per_view); rows are the edge points, then x and y of every corner. The edge rows'
        geometry at the last x is kept: the Jacobian at an x whose residuals were just evaluated
        (Levenberg-Marquardt's accepted step) costs only its assembly."""
        intr, shape, poses, offsets = self.unpack(x, intr0)
        K, D = camera_from_intrinsics(intr)
        R, dR, t = self.rotations(poses)
        if self.n_edge:
            fit = self._edge_fit(x, intr0, K, D, R, t, shape, offsets)
            f = fit.f
            Jg, Jv = self._edge_jacobian(fit, K, D, R, dR) if jac else (np.zeros((0, self.ng)),
                                                                       np.zeros((0, self.per_view)))
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
        """IRLS weights w = psi(r) / r of the soft-L1 loss, 1 / sqrt(1 + (r / s)^2); 1 for least
        squares (``loss_scale`` infinite)."""
        if not np.isfinite(loss_scale):
            return np.ones(len(f))
        return 1.0 / np.sqrt(1 + (f / loss_scale) ** 2)

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float:
        """Soft-L1 cost s^2 sum (sqrt(1 + (r / s)^2) - 1); sum r^2 / 2 for least squares."""
        if not np.isfinite(loss_scale):
            return 0.5 * float(np.sum(f * f))
        z = (f / loss_scale) ** 2
        return float(loss_scale**2 * np.sum(np.sqrt(1 + z) - 1))

    def loss_derivatives(self, f: np.ndarray, loss_scale: float) -> tuple[np.ndarray, np.ndarray]:
        """(psi, psi') per row: the first and second derivatives of the loss at the residuals. For
        soft-L1, psi = w r and psi' = w^3 with the IRLS weight w (least squares: r and 1). An
        M-estimator's covariance is A^-1 B A^-1 with A = J^T diag(psi') J and B = cov(J^T psi)
        (Huber, "Robust Statistics", 1981, sec. 7.6), not the IRLS weights in both."""
        w = self.robust_weights(f, loss_scale)
        return w * f, w**3

    def _per_view(self, A: np.ndarray, M: np.ndarray) -> np.ndarray:
        """Rows of A (n, ..., 3) times their view's matrix M[v] (3, k): one product per view (the
        edge rows of a view are contiguous)."""
        out = np.empty((*A.shape[:-1], M.shape[-1]))
        flat, out_flat = A.reshape(-1, A.shape[-1]), out.reshape(-1, M.shape[-1])
        k = int(np.prod(A.shape[1:-1]))  # rows of the flattened array per point
        for v, sl in enumerate(self.edge_slices):
            out_flat[k * sl.start:k * sl.stop] = flat[k * sl.start:k * sl.stop] @ M[v]
        return out

    def _rays(self, K: np.ndarray, D: np.ndarray) -> np.ndarray:
        """Unit rays of the edge points for the camera (K, D); kept while K and D stay (held
        intrinsics)."""
        key = K.tobytes() + np.asarray(D, float).tobytes()
        if self._ray_cache is None or self._ray_cache[0] != key:
            if self._compiled:
                from . import edge_row_kernels

                # Newton from the last camera's rays: an optimiser's next camera is near it
                start = self._ray_cache[1] if self._ray_cache is not None else np.zeros((0, 3))
                rays = np.empty((self.n_edge, 3))
                edge_row_kernels.edge_rays(np.ascontiguousarray(self.pts, float), *self._kernel_camera(K, D), start,
                                           rays)
            else:
                rays = self.lens.undistort(pixels_to_normalized(self.pts, K), D, strict=False)
            self._ray_cache = (key, rays)
        return self._ray_cache[1]

    def _edge_fit(self, x: np.ndarray, intr0: np.ndarray, K: np.ndarray, D: np.ndarray, R: np.ndarray,
                  t: np.ndarray, shape: np.ndarray, offsets: np.ndarray) -> EdgeFit:
        """The edge rows at x (module docstring): each point's foot point on the imaged circle, the
        outward normal there and the signed distance; the last one is kept (:meth:`evaluate`). A flat
        sheet (no shape parameter) in the board's x, y only."""
        key = x.tobytes() + intr0.tobytes()
        if self._fit_cache is not None and self._fit_cache[0] == key:
            return self._fit_cache[1]
        vi = self.view_of_pt
        flat = not self.shape_idx
        if self._compiled:
            fit = self._compiled_fit(K, D, R, t, offsets)
            self._fit_cache = (key, fit)
            return fit
        Rt = np.transpose(R, (0, 2, 1))
        Rb = Rt[:, :2, :] if flat else Rt  # board coordinates -> camera directions, as rows
        tv = t[vi]
        rays = self._rays(K, D)
        # the ray's intersection with the plane of its circle (z = 0, or the warped circle's height)
        lam = np.sum(R[:, :, 2] * t, 1)[vi] / self._per_view(rays, R[:, :, 2:])[:, 0]
        ctr = self.centers
        if not flat:
            ctr3 = self.board(self.centers, shape)[0]
            lam = (np.sum(R[:, :, 2] * t, 1)[vi] + ctr3[:, 2]) / self._per_view(rays, R[:, :, 2:])[:, 0]
            ctr = ctr3[:, :2]
        rel = self._per_view(rays * lam[:, None] - tv, R[:, :, :2]) - ctr  # R^T (X - t), as rows
        rho = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        u = rel / rho[:, None]
        r = self.radii[:, None]
        s1 = 1 + shape[0]
        dPds = np.zeros((0, 3, 3))
        for step in range(2):
            # the circle point at angle u, drawn on the printed sheet (each point at its own z)
            if flat:
                Q, tang = self.centers + r * u, np.stack([-u[:, 1], u[:, 0]], 1)
            else:
                Q, dPds, slope = self.board(self.centers + r * u, shape)
                tang = np.stack([-u[:, 1], s1 * u[:, 0], slope[:, 0] * -u[:, 1] + slope[:, 1] * u[:, 0]], 1)
            Xc = self._per_view(Q, Rb) + tv
            q, dqdX = project_with_point_jacobian(Xc, K, D, self.lens)
            ti = _times(dqdX, self._per_view(tang, Rb))  # image of the circle's tangent (per radian / r)
            if step:
                break
            # slide Q along the circle to the image foot point of u (one Gauss-Newton step on the
            # angle): the radial point of the plane is not the nearest in a perspective image, and
            # the Jacobian below is exact only at the foot point
            dq, e = ti * r, self.pts - q
            dth = (dq[:, 0] * e[:, 0] + dq[:, 1] * e[:, 1]) / np.maximum(dq[:, 0] * dq[:, 0] + dq[:, 1] * dq[:, 1],
                                                                        1e-30)
            c, s_ = np.cos(dth), np.sin(dth)
            u = np.stack([c * u[:, 0] - s_ * u[:, 1], s_ * u[:, 0] + c * u[:, 1]], 1)
        radial = u if flat else np.stack([u[:, 0], s1 * u[:, 1], slope[:, 0] * u[:, 0] + slope[:, 1] * u[:, 1]], 1)
        ri = _times(dqdX, self._per_view(radial, Rb))  # image of the outward radius
        ti /= np.maximum(np.hypot(ti[:, 0], ti[:, 1]), 1e-15)[:, None]
        orient = np.sign(ri[:, 0] * ti[:, 1] - ri[:, 1] * ti[:, 0])
        nrm = np.stack([ti[:, 1], -ti[:, 0]], 1) * orient[:, None]  # outward unit normal in the image
        e = self.pts - q
        f = (nrm[:, 0] * e[:, 0] + nrm[:, 1] * e[:, 1]) - self.signs * offsets[vi]
        fit = EdgeFit(f, nrm, Q, Xc, dqdX, dPds)
        self._fit_cache = (key, fit)
        return fit

    @property
    def _compiled(self) -> bool:
        """Whether the edge rows run in the compiled kernels (:mod:`.edge_row_kernels`: a flat target,
        a polynomial lens)."""
        return not self.shape_idx and isinstance(self.lens, PolynomialModel)

    def _kernel_camera(self, K: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(fx, fy, cx, cy, skew) and the 8 rational coefficients, as the kernels take them."""
        D = np.asarray(D, float).reshape(-1)
        return np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]]), np.r_[D, np.zeros(8 - len(D))]

    def _compiled_fit(self, K: np.ndarray, D: np.ndarray, R: np.ndarray, t: np.ndarray, offsets: np.ndarray
                      ) -> EdgeFit:
        """:meth:`_edge_fit` by :func:`.edge_row_kernels.edge_fit`."""
        from . import edge_row_kernels

        n = self.n_edge
        f, nrm, Q, Xc, dqdX = np.empty(n), np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 3)), np.empty((n, 2, 3))
        k, d8 = self._kernel_camera(K, D)
        def c64(a: np.ndarray) -> np.ndarray:  # the one argument type the kernels are compiled for
            return np.ascontiguousarray(a, np.float64)

        edge_row_kernels.edge_fit(pts=c64(self.pts), rays=self._rays(K, D), vi=self.view_of_pt,
                                  centers=c64(self.centers), radii=c64(self.radii), signs=self.signs,
                                  offsets=c64(offsets), R=c64(R), t=c64(t), K=k, D=d8, f=f, nrm=nrm, Q=Q, Xc=Xc,
                                  dqdX=dqdX)
        return EdgeFit(f, nrm, Q, Xc, dqdX, np.zeros((0, 3, 3)))

    def _edge_jacobian(self, fit: EdgeFit, K: np.ndarray, D: np.ndarray, R: np.ndarray, dR: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        """dF/d globals and dF/d own view of the edge rows at ``fit``: -n^T dq/d theta at the foot point."""
        if self._compiled:
            from . import edge_row_kernels

            Jg, Jv = np.zeros((len(fit.f), self.ng)), np.empty((len(fit.f), self.per_view))
            k, d8 = self._kernel_camera(K, D)
            edge_row_kernels.edge_jacobian(nrm=fit.nrm, Q=fit.Q, Xc=fit.Xc, dqdX=fit.dqdX, vi=self.view_of_pt,
                                           signs=self.signs, K=k, D=d8, n_coef=self.lens.n,
                                           free=np.asarray(self.free, np.int64),
                                           dR=np.ascontiguousarray(dR[:, : self.dof - 3]),
                                           use_offsets=self.use_offsets, Jg=Jg, Jv=Jv)
            return Jg, Jv
        nrm = fit.nrm
        h = nrm[:, 0, None] * fit.dqdX[:, 0] + nrm[:, 1, None] * fit.dqdX[:, 1]  # n^T dq/dX
        Jg = np.zeros((len(fit.f), self.ng))
        nf = len(self.free)
        if nf:
            dqdI = project_with_jacobians(fit.Xc, K, D, self.lens)[2][:, :, self.free]
            Jg[:, :nf] = -(nrm[:, 0, None] * dqdI[:, 0] + nrm[:, 1, None] * dqdI[:, 1])
        if self.shape_idx:
            g = self._per_view(h, R)  # n^T dq/dP
            Jg[:, nf:self.n_base] = -np.einsum("nk,nks->ns", g, fit.dPds[:, :, self.shape_idx])
        Jv = np.empty((len(fit.f), self.per_view))
        # n^T dq/dX . (dR/drv_k Q): the outer product h Q^T against each view's dR/drv_k
        nr, kq = self.dof - 3, fit.Q.shape[1]  # Q in the board's x, y (flat) or x, y, z
        hQ = (h[:, :, None] * fit.Q[:, None, :]).reshape(-1, 3 * kq)
        dRt = dR[..., :kq].reshape(len(dR), nr, 3 * kq).transpose(0, 2, 1)
        for v, sl in enumerate(self.edge_slices):
            Jv[sl, :nr] = -(hQ[sl] @ dRt[v])
        Jv[:, nr:self.dof] = -h
        if self.use_offsets:
            Jv[:, self.dof] = -self.signs
        return Jg, Jv

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
        # the rows view by view (one gather, unless they are in that order already), then slices
        order, bounds = self._view_order()
        if order is not None:
            f, Jg, Jv, w = f[order], Jg[order], Jv[order], w[order]
        Jvw = Jv * w[:, None]
        for i in range(self.nv):
            s, a, b = ng + i * pv, bounds[i], bounds[i + 1]
            A[s:s + pv, s:s + pv] = Jv[a:b].T @ Jvw[a:b]
            A[:ng, s:s + pv] = Jg[a:b].T @ Jvw[a:b]
            A[s:s + pv, :ng] = A[:ng, s:s + pv].T
            g[s:s + pv] = Jvw[a:b].T @ f[a:b]
        return A, g

    def _view_order(self) -> tuple[np.ndarray | None, list[int]]:
        """The rows sorted view by view (None: they are) and each view's first row in that order."""
        key = id(self.rows_of_view)  # subclasses set their rows once, after this class's __init__
        if self._order_cache is None or self._order_cache[0] != key:
            order = np.concatenate(self.rows_of_view) if self.rows_of_view else np.zeros(0, int)
            bounds = [0, *np.cumsum([len(r) for r in self.rows_of_view]).tolist()]
            self._order_cache = (key, None if np.array_equal(order, np.arange(len(order))) else order, bounds)
        return self._order_cache[1], self._order_cache[2]

    def dense_jacobian(self, Jg: np.ndarray, Jv: np.ndarray) -> np.ndarray:
        """The full Jacobian (rows, parameters), for tests and small problems."""
        J = np.zeros((len(Jg), self.ng + self.per_view * self.nv))
        J[:, : self.ng] = Jg
        for i, rows in enumerate(self.rows_of_view):
            s = self.ng + i * self.per_view
            J[rows, s:s + self.per_view] = Jv[rows]
        return J


def camera_from_intrinsics(intr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    return K, intr[5:].copy()
