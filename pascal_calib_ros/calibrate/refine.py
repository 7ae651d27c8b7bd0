"""Joint nonlinear refinement of intrinsics, plumb_bob distortion, poses and edge offsets.

Minimises, with a robust (soft L1) loss, the geometric distance of every subpixel edge point to
the image of its circle, plus the reprojection error of checkerboard corners if any:

- an edge point u is undistorted, its ray is intersected with the view's target plane, the plane
  point's direction from the circle centre gives the nearest circle point Q (in the plane); Q and
  two neighbours (along the tangent and the radius) are projected; the residual is the distance of
  u from the tangent line at q = proj(Q), signed positive on the circle's outer side;
- each view has an edge offset delta (pixels): a dark-inside edge (ring outer, disc) is expected
  at +delta, a dark-outside edge (ring inner) at -delta. Blur seen through a display gamma moves
  the two ring edges in opposite directions by the same amount, so delta is observable and
  absorbs the bias (PAPER.md: 0.02 px of bias moves f by ~0.7 %).

Poses have 6 dof (rvec, t) or 5 for a target with a single circle centre (rotation about the
ring's axis unobservable). Solved by Levenberg-Marquardt with IRLS weights; Jacobians by forward
differences grouped by the block structure (intrinsics x all rows, each view's parameters x its
rows only).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.camera import distort, normalized_to_pixels, pixels_to_normalized, undistort

INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "skew", "k1", "k2", "p1", "p2", "k3")

DISTORTION_MODELS = {
    "plumb_bob": ("k1", "k2", "p1", "p2", "k3"),
    "plumb_bob_k3_fixed": ("k1", "k2", "p1", "p2"),
    "radial": ("k1", "k2"),
    "none": (),
}


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


def _rotations(rv: np.ndarray) -> np.ndarray:
    """Vectorised Rodrigues: (V, 3) -> (V, 3, 3)."""
    th = np.linalg.norm(rv, axis=1)
    small = th < 1e-12
    k = rv / np.where(small, 1.0, th)[:, None]
    kx = np.zeros((len(rv), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2] = -k[:, 2], k[:, 1]
    kx[:, 1, 0], kx[:, 1, 2] = k[:, 2], -k[:, 0]
    kx[:, 2, 0], kx[:, 2, 1] = -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    R = np.eye(3)[None] + s * kx + (1 - c) * (kx @ kx)
    if np.any(small):
        r = rv[small]
        sk = np.zeros((len(r), 3, 3))
        sk[:, 0, 1], sk[:, 0, 2] = -r[:, 2], r[:, 1]
        sk[:, 1, 0], sk[:, 1, 2] = r[:, 2], -r[:, 0]
        sk[:, 2, 0], sk[:, 2, 1] = -r[:, 1], r[:, 0]
        R[small] = np.eye(3)[None] + sk
    return R


class Problem:
    """Parameter layout and residuals of one refinement."""

    def __init__(self, views: list[ViewData], dof: int, free_intrinsics: tuple[str, ...], use_offsets: bool,
                 loss_scale: float = 0.3):
        self.views = views
        self.dof = dof
        self.use_offsets = use_offsets
        self.free = [INTRINSIC_NAMES.index(n) for n in free_intrinsics]
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
        self.n_corner = len(self.corners)

    # -- parameter packing -------------------------------------------------------------
    def pack(self, intr: np.ndarray, poses: list[np.ndarray], offsets: np.ndarray) -> np.ndarray:
        per = [np.concatenate([p, [o]]) if self.use_offsets else p for p, o in zip(poses, offsets, strict=True)]
        return np.concatenate([intr[self.free], *per])

    def unpack(self, x: np.ndarray, intr0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        intr = intr0.copy()
        nf = len(self.free)
        intr[self.free] = x[:nf]
        vp = x[nf:].reshape(self.nv, self.per_view)
        poses = vp[:, : self.dof]
        offsets = vp[:, self.dof] if self.use_offsets else np.zeros(self.nv)
        return intr, poses, offsets

    def pose_matrices(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.dof == 6:
            rv, t = poses[:, :3], poses[:, 3:6]
        else:
            rv = np.concatenate([poses[:, :2], np.zeros((len(poses), 1))], 1)
            t = poses[:, 2:5]
        return _rotations(rv), t

    # -- residuals --------------------------------------------------------------------
    def residuals(self, x: np.ndarray, intr0: np.ndarray) -> np.ndarray:
        intr, poses, offsets = self.unpack(x, intr0)
        K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
        D = intr[5:10]
        R, t = self.pose_matrices(poses)
        out = [self.edge_residuals(K, D, R, t, offsets)]
        if self.n_corner:
            out.append(self.corner_residuals(K, D, R, t).ravel())
        r = np.concatenate(out)
        return np.where(np.isfinite(r), r, 1e3)

    def edge_residuals(self, K: np.ndarray, D: np.ndarray, R: np.ndarray, t: np.ndarray,
                       offsets: np.ndarray) -> np.ndarray:
        vi = self.view_of_pt
        Rv, tv = R[vi], t[vi]
        xn = undistort(pixels_to_normalized(self.pts, K), D, iterations=6)
        d = np.concatenate([xn, np.ones((len(xn), 1))], 1)
        n = Rv[:, :, 2]
        lam = np.sum(n * tv, 1) / np.sum(n * d, 1)
        X = d * lam[:, None]
        P = np.einsum("nji,nj->ni", Rv, X - tv)  # R^T (X - t)
        rel = P[:, :2] - self.centers
        rho = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        u = rel / rho[:, None]
        eps = 1e-3 * self.radii[:, None]
        Q = self.centers + self.radii[:, None] * u
        tang = np.stack([-u[:, 1], u[:, 0]], 1)
        q = self._project_local(K, D, Rv, tv, Q)
        qt = self._project_local(K, D, Rv, tv, Q + eps * tang)
        qr = self._project_local(K, D, Rv, tv, Q + eps * u)
        ti = qt - q
        ti /= np.maximum(np.hypot(ti[:, 0], ti[:, 1]), 1e-15)[:, None]
        ri = qr - q
        orient = np.sign(ri[:, 0] * ti[:, 1] - ri[:, 1] * ti[:, 0])
        a = self.pts - q
        dist = (a[:, 0] * ti[:, 1] - a[:, 1] * ti[:, 0]) * orient
        return dist - self.signs * offsets[vi]

    @staticmethod
    def _project_local(K: np.ndarray, D: np.ndarray, Rv: np.ndarray, tv: np.ndarray, P2: np.ndarray) -> np.ndarray:
        X = Rv[:, :, 0] * P2[:, 0:1] + Rv[:, :, 1] * P2[:, 1:2] + tv
        return normalized_to_pixels(distort(X[:, :2] / X[:, 2:3], D), K)

    def corner_residuals(self, K: np.ndarray, D: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        vi = self.view_of_corner
        return self._project_local(K, D, R[vi], t[vi], self.corner_obj) - self.corners

    def view_columns(self) -> tuple[int, np.ndarray, np.ndarray]:
        """(number of intrinsic columns, per-view column offsets, view of each residual row)."""
        nf = len(self.free)
        offsets = nf + self.per_view * np.arange(self.nv)
        rows = np.concatenate([self.view_of_pt, np.repeat(self.view_of_corner, 2)])
        return nf, offsets, rows


@dataclass
class LMResult:
    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    weights: np.ndarray
    cost: float
    nfev: int
    iterations: int
    success: bool
    message: str


def _jacobian(fun: object, x: np.ndarray, f0: np.ndarray, prob: Problem, intr0: np.ndarray) -> tuple[np.ndarray, int]:
    """Forward differences exploiting the block structure: each intrinsic column alone, then each
    per-view column j perturbed in every view at once (a view's rows depend on its own block)."""
    nf, offs, rows = prob.view_columns()
    J = np.zeros((len(f0), len(x)))
    nfev = 0
    for j in range(nf):
        h = 1e-6 * max(abs(x[j]), 1e-2)
        xp = x.copy()
        xp[j] += h
        J[:, j] = (prob.residuals(xp, intr0) - f0) / h
        nfev += 1
    for j in range(prob.per_view):
        cols = offs + j
        h = 1e-7 * np.maximum(np.abs(x[cols]), 1e-2)
        xp = x.copy()
        xp[cols] += h
        df = prob.residuals(xp, intr0) - f0
        nfev += 1
        J[np.arange(len(f0)), cols[rows]] = df / h[rows]
    return J, nfev


def levenberg_marquardt(prob: Problem, x0: np.ndarray, intr0: np.ndarray, loss_scale: float,
                        max_iter: int = 60, tol: float = 1e-10) -> LMResult:
    """Levenberg-Marquardt with iteratively reweighted soft-L1 loss rho(z) = 2 (sqrt(1 + z) - 1),
    z = (r / f)^2, weights 1 / sqrt(1 + z); dense normal equations (the parameter count is small)."""
    x = x0.copy()
    f = prob.residuals(x, intr0)
    nfev = 1

    def robust_cost(r: np.ndarray) -> float:
        z = (r / loss_scale) ** 2
        return float(loss_scale**2 * np.sum(np.sqrt(1 + z) - 1))

    cost = robust_cost(f)
    lam = 1e-3
    message, success = "maximum iterations reached", False
    J = np.zeros((len(f), len(x)))
    w = np.ones(len(f))
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        J, n = _jacobian(prob.residuals, x, f, prob, intr0)
        nfev += n
        w = 1.0 / np.sqrt(1 + (f / loss_scale) ** 2)
        Jw = J * w[:, None]
        A = J.T @ Jw
        g = Jw.T @ f
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
            fn = prob.residuals(xn, intr0)
            nfev += 1
            cn = robust_cost(fn)
            if cn < cost:
                rel = (cost - cn) / max(cost, 1e-300)
                x, f, cost = xn, fn, cn
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
    w = 1.0 / np.sqrt(1 + (f / loss_scale) ** 2)
    return LMResult(x, f, J, w, cost, nfev, it, success, message)


def refine(views: list[ViewData], K0: np.ndarray, D0: np.ndarray, poses0: list[np.ndarray], dof: int,
           distortion: str = "plumb_bob", zero_skew: bool = True, use_offsets: bool = True,
           loss_scale: float = 0.3, max_iter: int = 60) -> RefineResult:
    """Least squares over K, D, poses and offsets (see the module docstring)."""
    if distortion not in DISTORTION_MODELS:
        raise ValueError(f"unknown distortion model {distortion!r}: {', '.join(DISTORTION_MODELS)}")
    free = ("fx", "fy", "cx", "cy") + (() if zero_skew else ("skew",)) + DISTORTION_MODELS[distortion]
    prob = Problem(views, dof, free, use_offsets, loss_scale)
    intr0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2], 0.0 if zero_skew else K0[0, 1], *np.asarray(D0, float)])
    for name in INTRINSIC_NAMES[5:]:
        if name not in free:  # coefficients the model does not estimate are held at zero
            intr0[INTRINSIC_NAMES.index(name)] = 0.0
    x0 = prob.pack(intr0, poses0, np.zeros(len(views)))
    sol = levenberg_marquardt(prob, x0, intr0, loss_scale, max_iter=max_iter)
    intr, poses, offsets = prob.unpack(sol.x, intr0)
    K = np.array([[intr[0], intr[4], intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    D = intr[5:10].copy()
    R, t = prob.pose_matrices(poses)
    er = prob.edge_residuals(K, D, R, t, offsets)
    per_view = [er[prob.view_of_pt == i] for i in range(len(views))]
    view_rms = np.array([np.sqrt(np.mean(r * r)) if len(r) else 0.0 for r in per_view])
    corner_rms = np.zeros(len(views))
    if prob.n_corner:
        cr = prob.corner_residuals(K, D, R, t)
        for i in range(len(views)):
            sel = prob.view_of_corner == i
            if sel.any():
                corner_rms[i] = float(np.sqrt(np.mean(np.sum(cr[sel] ** 2, 1))))
    # standard deviations from the Gauss-Newton covariance s^2 (J^T J)^-1
    J = sol.jac
    dof_res = max(len(sol.fun) - len(sol.x), 1)
    s2 = float(np.sum(sol.weights * sol.fun**2) / dof_res)
    std: dict[str, float] = {}
    try:
        cov = np.linalg.pinv(J.T @ (J * sol.weights[:, None])) * s2
        for k, idx in enumerate(prob.free):
            std[INTRINSIC_NAMES[idx]] = float(np.sqrt(max(cov[k, k], 0.0)))
    except np.linalg.LinAlgError:
        pass
    return RefineResult(K, D, [p.copy() for p in poses], offsets, std, view_rms, corner_rms,
                        float(np.sqrt(np.mean(er * er))), per_view, float(sol.cost), int(sol.nfev),
                        bool(sol.success), str(sol.message))
