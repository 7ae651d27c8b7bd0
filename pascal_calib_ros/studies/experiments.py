"""The seed paper's experiments, reproduced honestly (``pascal-calib experiment NAME``).

Simulation protocol of the paper: fu=500, fv=600, u0=400, v0=300, s=0, 800x600 image; per view a
ring (outer radius 1, inner 0.5; its image ~110-150 px in radius), a separate disc (radius 0.6,
for Huang) and a 9x6 grid of known points (for Zhang) on one plane tilted 20-50 degrees, 3.4-4.6
units away; 100 points sampled on each circle's image,
Gaussian noise sigma on the points, conics refitted; 50 trials per sigma; 3 views (and 10).

- ``layouts`` (Figure 4): five layouts of the Pascal points, on the fitted conic and raw.
- ``methods`` (Figure 5): pt1, pt2, ring, huang, zhang, ring_refined on identical data.
- ``literal``: the paper's equations exactly as written (one circle, no extra cue).
- ``board`` (Table 1 analog): rendered images of ``pascal_board_a3``, every method.
- ``reconstruct`` (Table 2 analog): two views of the checkerboard reconstructed with each K.
"""

from __future__ import annotations

import csv
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..calibrate import CalibrationError, CalibrationOptions, ViewData, calibrate, refine
from ..detect import Detection, detect_target
from ..geometry import (
    PT1_STARTS,
    CircularPointError,
    ConicFitError,
    DegenerateViewsError,
    Ellipse,
    ImageSize,
    centre_image_from_ring,
    circular_point_pt2,
    circular_points_from_ring,
    circular_points_huang,
    circular_points_pt1,
    fit_conic,
    fit_homography,
    iac_from_circular_points,
    pascal_condition,
    rodrigues,
    vanishing_line_from_centre,
)
from ..targets import Ring, Target, resolve_target

K_PAPER = np.array([[500.0, 0.0, 400.0], [0.0, 600.0, 300.0], [0.0, 0.0, 1.0]])
W, H = 800, 600
SIGMAS = tuple(np.round(np.arange(0, 2.01, 0.25), 2))
COLUMNS = ["method", "layout", "sigma", "n_views", "trials", "failures", "mean_fu", "std_fu", "mean_fv", "std_fv",
           "mean_u0", "std_u0", "mean_v0", "std_v0", "mean_s", "std_s"]
LAYOUTS = {  # quadrant (of the fitted ellipse's axes) of each of the five Pascal points
    "average": (0, 1, 2, 3, 0),
    "three-one": (0, 0, 0, 2, 0),
    "half": (0, 0, 1, 1, 0),
    "two-two": (0, 0, 2, 2, 0),
    "all": (0, 0, 0, 0, 0),
}
RING_OUT, RING_IN, DISC_C, DISC_R = 1.0, 0.5, (1.9, 0.5), 0.6
GRID = np.stack(np.meshgrid(np.linspace(-1.4, 1.4, 9), np.linspace(-0.9, 0.9, 6)), -1).reshape(-1, 2)


class Failure(Exception):
    pass


@dataclass
class SimView:
    H: np.ndarray
    pts: dict[str, np.ndarray]  # noisy image points per circle: outer, inner, disc
    angles: dict[str, np.ndarray]  # plane angle of each sample
    conics: dict[str, np.ndarray]  # refitted
    grid: np.ndarray  # noisy grid points (Zhang)
    i_true: np.ndarray


def _circle_points(H: np.ndarray, c: tuple[float, float], r: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P = np.stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t), np.ones(n)], 1) @ H.T
    return P[:, :2] / P[:, 2:3], t


def random_sim_view(rng: np.random.Generator, sigma: float, n_points: int = 100) -> SimView:
    """One view of the simulated plane with noisy points and refitted conics (all in the image)."""
    for _ in range(1000):
        tilt = np.radians(rng.uniform(20, 50))
        axis = rng.uniform(0, 2 * np.pi)
        R = rodrigues(tilt * np.array([np.cos(axis), np.sin(axis), 0.0])) @ rodrigues(
            np.array([0, 0, rng.uniform(-np.pi, np.pi)]))
        t = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.3, 0.3), rng.uniform(3.4, 4.6)])
        Hm = K_PAPER @ np.column_stack([R[:, 0], R[:, 1], t])
        outline, _ = _circle_points(Hm, DISC_C, DISC_R, 64)
        ring, _ = _circle_points(Hm, (0, 0), RING_OUT, 64)
        g = np.c_[GRID, np.ones(len(GRID))] @ Hm.T
        allp = np.concatenate([outline, ring, g[:, :2] / g[:, 2:3]])
        if np.all((allp > 5) & (allp < [W - 5, H - 5])) and np.all(g[:, 2] > 0):
            break
    pts, angles, conics = {}, {}, {}
    for name, c, r in (("outer", (0.0, 0.0), RING_OUT), ("inner", (0.0, 0.0), RING_IN), ("disc", DISC_C, DISC_R)):
        p, a = _circle_points(Hm, c, r, n_points)
        p = p + rng.normal(0, sigma, p.shape) if sigma > 0 else p
        pts[name], angles[name] = p, a
        conics[name] = fit_conic(p)
    g = np.c_[GRID, np.ones(len(GRID))] @ Hm.T
    grid = g[:, :2] / g[:, 2:3]
    grid = grid + rng.normal(0, sigma, grid.shape) if sigma > 0 else grid
    i = Hm @ np.array([1, 1j, 0])
    return SimView(Hm, pts, angles, conics, grid, i / i[2])


def layout_points(view: SimView, layout: str, source: str) -> np.ndarray:
    """Five Pascal points in the layout's quadrants, on the fitted conic or raw noisy points."""
    e = Ellipse.from_conic(view.conics["outer"])
    quads = LAYOUTS[layout]
    counts = {q: quads.count(q) for q in set(quads)}
    seen: dict[int, int] = {}
    targets = []
    for q in quads:
        j = seen.get(q, 0)
        seen[q] = j + 1
        targets.append(q * np.pi / 2 + (j + 0.5) * (np.pi / 2) / counts[q])
    targets_a = np.array(targets)
    if source == "fitted":
        c, s = np.cos(e.angle), np.sin(e.angle)
        x, y = e.a * np.cos(targets_a), e.b * np.sin(targets_a)
        return np.stack([e.cx + c * x - s * y, e.cy + s * x + c * y], 1)
    raw = view.pts["outer"]
    d = raw - [e.cx, e.cy]
    c, s = np.cos(e.angle), np.sin(e.angle)
    local = np.stack([(c * d[:, 0] + s * d[:, 1]) / e.a, (-s * d[:, 0] + c * d[:, 1]) / e.b], 1)
    ang = np.mod(np.arctan2(local[:, 1], local[:, 0]), 2 * np.pi)
    idx = [int(np.argmin(np.abs(np.angle(np.exp(1j * (ang - a)))))) for a in targets_a]
    return raw[idx]


def _line(view: SimView) -> np.ndarray:
    c = centre_image_from_ring(view.conics["outer"], view.conics["inner"])
    return vanishing_line_from_centre(view.conics["outer"], c)


def solve_view(view: SimView, method: str, layout: str = "average", source: str = "fitted") -> np.ndarray:
    if method == "ring":
        return circular_points_from_ring(view.conics["outer"], view.conics["inner"])[0]
    if method == "huang":
        return circular_points_huang(view.conics["outer"], view.conics["disc"])[0]
    pts = layout_points(view, layout, source)
    if method == "pt2":
        res = circular_point_pt2(pts, _line(view))
    elif method == "pt1":
        for start in PT1_STARTS:
            res = circular_points_pt1(pts, _line(view), start)
            if res.converged:
                break
    else:
        raise ValueError(method)
    if not res.converged:
        raise Failure(f"{method} did not converge")
    return res.point


def _k_closed_form(views: list[SimView], method: str, layout: str = "average", source: str = "fitted") -> np.ndarray:
    pts = [solve_view(v, method, layout, source) for v in views]
    return iac_from_circular_points(pts, ImageSize(W, H), zero_skew=False).K


def _reprojection_rms(K: np.ndarray, Hs: list[np.ndarray], views: list[SimView]) -> float:
    """RMS of the grid reprojection with Zhang's extrinsics from H and K (Zhang 2000, sec. 3.1)."""
    err = []
    Ki = np.linalg.inv(K)
    for Hm, v in zip(Hs, views, strict=True):
        lam = 1 / np.linalg.norm(Ki @ Hm[:, 0])
        r1, r2, t = lam * Ki @ Hm[:, 0], lam * Ki @ Hm[:, 1], lam * Ki @ Hm[:, 2]
        P = (np.c_[GRID, np.ones(len(GRID))] @ np.column_stack([r1, r2, t]).T) @ K.T
        err.append(P[:, :2] / P[:, 2:3] - v.grid)
    return float(np.sqrt(np.mean(np.concatenate(err) ** 2)))


def _k_zhang(views: list[SimView]) -> np.ndarray:
    """Zhang's method: homographies (float64 DLT) -> i' = h1 + i h2 -> w -> K, then OpenCV's
    maximum-likelihood refinement; the refinement is kept only if it lowers the reprojection
    error (OpenCV works in float32, which limits it to ~1e-5 px on noise-free data)."""
    Hs = [fit_homography(GRID, v.grid) for v in views]
    K_cf = iac_from_circular_points([Hm[:, 0] + 1j * Hm[:, 1] for Hm in Hs], ImageSize(W, H), zero_skew=False).K
    obj = np.c_[GRID, np.zeros(len(GRID))].astype(np.float32)
    img = [v.grid.astype(np.float32).reshape(-1, 1, 2) for v in views]
    flags = (cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
             | cv2.CALIB_USE_INTRINSIC_GUESS)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-12)
    K0 = K_cf.copy()
    K0[0, 1] = 0.0
    rms_cv, K_cv, _, _, _ = cv2.calibrateCamera([obj] * len(views), img, (W, H), K0, np.zeros(5), flags=flags,
                                                criteria=crit)
    return np.asarray(K_cv) if rms_cv < _reprojection_rms(K_cf, Hs, views) else K_cf


def _k_ring_refined(views: list[SimView]) -> np.ndarray:
    from ..calibrate import PlanePose, pose_to_params

    K0 = _k_closed_form(views, "ring")
    data, poses = [], []
    for v in views:
        pts = np.concatenate([v.pts["outer"], v.pts["inner"]])
        n1, n2 = len(v.pts["outer"]), len(v.pts["inner"])
        data.append(ViewData(pts, np.zeros((n1 + n2, 2)), np.r_[np.full(n1, RING_OUT), np.full(n2, RING_IN)],
                             np.r_[np.ones(n1), -np.ones(n2)], np.r_[np.zeros(n1), np.ones(n2)].astype(int)))
        # pose from the closed-form K: normal from the vanishing line, centre from the pencil
        from ..calibrate import pose_from_view
        from ..detect import CircleEdge

        det = Detection(W, H, [CircleEdge(0, v.pts["outer"], v.conics["outer"], 1.0, 0.0),
                               CircleEdge(1, v.pts["inner"], v.conics["inner"], 1.0, 0.0)])
        pose: PlanePose = pose_from_view(det, _SIM_TARGET, K0, (0.0, 0.0))
        poses.append(pose_to_params(pose, 5))
    res = refine(data, K0, np.zeros(5), poses, 5, distortion="none", zero_skew=False, use_offsets=False)
    return res.K


_SIM_TARGET = Target(name="sim_ring", sheet=(10.0, 10.0), rings=(Ring((0.0, 0.0), RING_OUT, RING_IN),))

SOLVERS: dict[str, Callable[[list[SimView]], np.ndarray]] = {
    "pt1": lambda vs: _k_closed_form(vs, "pt1"),
    "pt2": lambda vs: _k_closed_form(vs, "pt2"),
    "ring": lambda vs: _k_closed_form(vs, "ring"),
    "huang": lambda vs: _k_closed_form(vs, "huang"),
    "zhang": _k_zhang,
    "ring_refined": _k_ring_refined,
}


def _row(method: str, layout: str, sigma: float, n_views: int, Ks: list[np.ndarray], trials: int) -> dict[str, Any]:
    row: dict[str, Any] = {"method": method, "layout": layout, "sigma": sigma, "n_views": n_views,
                           "trials": trials, "failures": trials - len(Ks)}
    arr = np.array([[K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]] for K in Ks]) if Ks else np.full((1, 5), np.nan)
    for k, name in enumerate(("fu", "fv", "u0", "v0", "s")):
        row[f"mean_{name}"] = float(np.mean(arr[:, k]))
        row[f"std_{name}"] = float(np.std(arr[:, k]))
    return row


def _trial_views(seed: int, sigma_index: int, trial: int, n_views: int, sigma: float) -> list[SimView]:
    rng = np.random.default_rng([seed, sigma_index, trial, n_views])
    for _ in range(20):
        try:
            return [random_sim_view(rng, sigma) for _ in range(n_views)]
        except ConicFitError:
            continue
    raise Failure("could not sample views")


def _progress(k: int, n: int, label: str) -> None:
    if sys.stderr.isatty():
        sys.stderr.write(f"\r[{k}/{n}] {label:<50}")
        sys.stderr.flush()
        if k == n:
            sys.stderr.write("\n")


def run_methods(trials: int, seed: int, view_counts: tuple[int, ...] = (3, 10)) -> list[dict[str, Any]]:
    rows = []
    total = len(view_counts) * len(SIGMAS)
    step = 0
    for n_views in view_counts:
        for si, sigma in enumerate(SIGMAS):
            step += 1
            _progress(step, total, f"methods: {n_views} views, sigma {sigma}")
            Ks: dict[str, list[np.ndarray]] = {m: [] for m in SOLVERS}
            for t in range(trials):
                views = _trial_views(seed, si, t, n_views, float(sigma))
                for m, solver in SOLVERS.items():
                    try:
                        Ks[m].append(solver(views))
                    except (Failure, CircularPointError, DegenerateViewsError, np.linalg.LinAlgError, cv2.error):
                        pass
            rows += [_row(m, "average", float(sigma), n_views, Ks[m], trials) for m in SOLVERS]
    return rows


def run_layouts(trials: int, seed: int) -> list[dict[str, Any]]:
    rows = []
    total = len(SIGMAS)
    for si, sigma in enumerate(SIGMAS):
        _progress(si + 1, total, f"layouts: sigma {sigma}")
        Ks: dict[tuple[str, str, str], list[np.ndarray]] = {}
        for t in range(trials):
            views = _trial_views(seed, si, t, 3, float(sigma))
            for method in ("pt2", "pt1"):
                for layout in LAYOUTS:
                    for source in ("fitted", "raw"):
                        key = (method, layout, source)
                        try:
                            Ks.setdefault(key, []).append(_k_closed_form(views, method, layout, source))
                        except (Failure, CircularPointError, DegenerateViewsError, np.linalg.LinAlgError):
                            Ks.setdefault(key, [])
        rows += [_row(m, f"{lay}/{src}", float(sigma), 3, K, trials) for (m, lay, src), K in Ks.items()]
    return rows


# -- the paper's equations exactly as written -------------------------------------------------
def pt2_literal(points5: np.ndarray, start: np.ndarray, iters: int = 80) -> np.ndarray:
    """Pascal(p1..p5, i') = 0 with i' = (x, y, 1) free (no vanishing line): one complex equation
    in two complex unknowns; minimum-norm complex Newton steps. Returns i'."""
    T = np.diag([1 / 400, 1 / 400, 1.0])
    pts = [T @ np.array([x, y, 1.0]) for x, y in points5]
    z = (T @ np.asarray(start, complex))[:2].astype(complex)
    for _ in range(iters):
        f = pascal_condition([*pts, np.array([z[0], z[1], 1.0])])
        J = np.empty(2, complex)
        for k in range(2):
            dz = np.zeros(2, complex)
            dz[k] = 1e-6
            J[k] = (pascal_condition([*pts, np.array([z[0] + dz[0], z[1] + dz[1], 1.0])]) - f) / 1e-6
        n2 = float(np.real(J @ np.conj(J)))
        if n2 == 0:
            break
        step = -f * np.conj(J) / n2
        z = z + step
        if np.linalg.norm(step) < 1e-12 * max(float(np.linalg.norm(z)), 1.0):
            break
    return np.linalg.solve(T, np.array([z[0], z[1], 1.0]))


def pt1_literal(points4: np.ndarray, start: np.ndarray, iters: int = 80) -> np.ndarray:
    """Pascal(a, b, c, d, i', conj(i')) = 0 with i' free: two real equations in four real unknowns;
    minimum-norm Gauss-Newton."""
    T = np.diag([1 / 400, 1 / 400, 1.0])
    pts = [T @ np.array([x, y, 1.0]) for x, y in points4]
    s = T @ np.asarray(start, complex)
    z = np.array([s[0].real, s[0].imag, s[1].real, s[1].imag])

    def res(zz: np.ndarray) -> np.ndarray:
        i_ = np.array([zz[0] + 1j * zz[1], zz[2] + 1j * zz[3], 1.0])
        f = pascal_condition([*pts, i_, np.conj(i_)])
        return np.array([f.real, f.imag])

    for _ in range(iters):
        r = res(z)
        J = np.stack([(res(z + dz) - r) / 1e-7 for dz in np.eye(4) * 1e-7], 1)
        step = -np.linalg.pinv(J) @ r
        z = z + step
        if np.linalg.norm(step) < 1e-12 * max(float(np.linalg.norm(z)), 1.0):
            break
    return np.linalg.solve(T, np.array([z[0] + 1j * z[1], z[2] + 1j * z[3], 1.0]))


def run_literal(trials: int, seed: int) -> list[dict[str, Any]]:
    rows = []
    for si, sigma in enumerate(SIGMAS):
        _progress(si + 1, len(SIGMAS), f"literal: sigma {sigma}")
        Ks: dict[tuple[str, str], list[np.ndarray]] = {}
        for t in range(trials):
            views = _trial_views(seed, si, t, 3, float(sigma))
            rng = np.random.default_rng([seed, si, t, 99])
            for start_kind in ("generic_start", "near_truth_start"):
                for method in ("pt2_literal", "pt1_literal"):
                    pts = []
                    for v in views:
                        if start_kind == "near_truth_start":
                            start = v.i_true * (1 + 0.01 * (rng.normal() + 1j * rng.normal()))
                            start[2] = 1.0
                        else:
                            start = np.array([W / 2 + 300 * rng.normal() + 300j * rng.normal(),
                                              H / 2 + 300 * rng.normal() + 300j * rng.normal(), 1.0])
                        five = layout_points(v, "average", "fitted")
                        pts.append(pt2_literal(five, start) if method == "pt2_literal"
                                   else pt1_literal(five[:4], start))
                    key = (method, start_kind)
                    try:
                        Ks.setdefault(key, []).append(iac_from_circular_points(pts, ImageSize(W, H)).K)
                    except (DegenerateViewsError, np.linalg.LinAlgError):
                        Ks.setdefault(key, [])
        rows += [_row(m, lay, float(sigma), 3, K, trials) for (m, lay), K in Ks.items()]
    return rows


# -- rendered board: Table 1 and Table 2 analogs ------------------------------------------------
def _board_sessions(trials: int, seed: int, k1: float, views: int = 10) -> list[tuple[Any, list[Detection]]]:
    from ..sim import SessionSpec, render_session_views

    target = resolve_target("pascal_board_a3")
    out = []
    for t in range(trials):
        _progress(t + 1, trials, "rendering board sessions (2456x2058)")
        spec = SessionSpec(width=2456, height=2058, focal=2400.0, k1=k1, views=views, seed=seed * 100 + t,
                           size_range=(0.5, 0.85), blur=1.2)
        cam, vs = render_session_views(target, spec)
        out.append((cam, [detect_target(v.image, target, name=str(v.meta["name"])) for v in vs]))
    return out


# (method, our refinement); zhang without ours is OpenCV's calibrateCamera (Zhang's method as OpenCV does it)
BOARD_METHODS = (("ring", False), ("pt1", False), ("pt2", False), ("huang", False), ("zhang", False),
                 ("ring", True))


def run_board(trials: int, seed: int) -> list[dict[str, Any]]:
    target = resolve_target("pascal_board_a3")
    sessions = _board_sessions(trials, seed, k1=-0.05)
    rows = []
    truth = sessions[0][0]
    for method, refined in BOARD_METHODS:
        Ks = []
        for _, dets in sessions:
            try:
                res = calibrate(dets, target, CalibrationOptions(method=method, refine=refined, zero_skew=False
                                                                 if not refined else True))
                Ks.append(res.K)
            except CalibrationError:
                pass
        name = "ring_refined" if (method == "ring" and refined) else method
        row = _row(name, "board", 0.0, len(sessions[0][1]), Ks, len(sessions))
        row["true_fu"], row["true_fv"] = truth.K[0, 0], truth.K[1, 1]
        row["true_u0"], row["true_v0"] = truth.K[0, 2], truth.K[1, 2]
        rows.append(row)
    return rows


def _decompositions(u1: np.ndarray, u2: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Homography decompositions (R, t, n) with every point in front of both cameras."""
    H, _ = cv2.findHomography(u1, u2, 0)
    if H is None:
        raise Failure("no homography between the views")
    _, Rs, ts, ns = cv2.decomposeHomographyMat(H, np.eye(3))
    out = []
    P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    for R, t, n in zip(Rs, ts, ns, strict=True):
        X = cv2.triangulatePoints(P1, np.hstack([R, t]), u1.T, u2.T)
        X = (X[:3] / X[3]).T
        if np.all(X[:, 2] > 0) and np.all((X @ R.T + t.ravel())[:, 2] > 0):
            out.append((R, t, n.ravel()))
    return out


def _reconstruct_angles(K: np.ndarray, D: np.ndarray, c1: np.ndarray, c2: np.ndarray, c3: np.ndarray, nx: int,
                        ny: int) -> tuple[float, float]:
    """Two-view reconstruction of the (planar) grid with K, from the corners of views 1 and 2:
    the inter-image homography of the undistorted normalised corners is decomposed into
    (R, t/d, n); of the two physically valid decompositions, the one whose plane normal agrees
    with the decomposition towards a third view is kept. The corners are triangulated and the
    mean angles between lines that should be parallel (rows with rows, columns with columns)
    and perpendicular (rows with columns) are returned, in degrees. No board dimension is used."""
    u = [cv2.undistortPoints(c.reshape(-1, 1, 2), K, D).reshape(-1, 2) for c in (c1, c2, c3)]
    d12, d13 = _decompositions(u[0], u[1]), _decompositions(u[0], u[2])
    if not d12 or not d13:
        raise Failure("no homography decomposition with the points in front of the cameras")
    R, t, _ = max(d12, key=lambda s: max(abs(float(s[2] @ o[2])) for o in d13))
    X = cv2.triangulatePoints(np.hstack([np.eye(3), np.zeros((3, 1))]), np.hstack([R, t]), u[0].T, u[1].T)
    X = (X[:3] / X[3]).T.reshape(ny, nx, 3)

    def direction(pts: np.ndarray) -> np.ndarray:
        c = pts - pts.mean(0)
        return np.linalg.svd(c)[2][0]

    rows = [direction(X[j]) for j in range(ny)]
    cols = [direction(X[:, i]) for i in range(nx)]

    def ang(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.degrees(np.arccos(np.clip(abs(a @ b), 0, 1))))

    par = [ang(a, b) for g in (rows, cols) for i, a in enumerate(g) for b in g[i + 1:]]
    perp = [ang(a, b) for a in rows for b in cols]
    return float(np.mean(par)), float(np.mean(perp))


def run_reconstruct(trials: int, seed: int) -> list[dict[str, Any]]:
    target = resolve_target("pascal_board_a3")
    board = target.checkerboard
    assert board is not None
    nx, ny = board.inner_corners
    sessions = _board_sessions(trials, seed + 7, k1=0.0, views=10)
    rows = []
    for method, refined in BOARD_METHODS:
        Ks, par, perp = [], [], []
        for _, dets in sessions:
            try:
                res = calibrate(dets[3:], target, CalibrationOptions(method=method, refine=refined))
                trio = [d.corners for d in dets[:3] if d.corners is not None]
                if len(trio) < 3:
                    continue
                a, b = _reconstruct_angles(res.K, res.D, trio[0], trio[1], trio[2], nx, ny)
                Ks.append(res.K)
                par.append(a)
                perp.append(b)
            except (CalibrationError, Failure, cv2.error):
                pass
        name = "ring_refined" if (method == "ring" and refined) else method
        row = _row(name, "two_views", 0.0, 2, Ks, len(sessions))
        row["mean_parallel_deg"] = float(np.mean(par)) if par else float("nan")
        row["mean_perpendicular_deg"] = float(np.mean(perp)) if perp else float("nan")
        rows.append(row)
    return rows


EXPERIMENTS: dict[str, tuple[Callable[[int, int], list[dict[str, Any]]], int]] = {
    "layouts": (run_layouts, 50),
    "methods": (run_methods, 50),
    "literal": (run_literal, 50),
    "board": (run_board, 3),
    "reconstruct": (run_reconstruct, 3),
}


def run_experiment(name: str, out: Path, trials: int | None = None, seed: int = 0) -> list[dict[str, Any]]:
    if name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {name!r}; choose from {', '.join(EXPERIMENTS)}")
    fn, default_trials = EXPERIMENTS[name]
    rows = fn(trials or default_trials, seed)
    out.mkdir(parents=True, exist_ok=True)
    keys = COLUMNS + [k for k in rows[0] if k not in COLUMNS]
    with open(out / f"{name}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    from .plots import plot_experiment

    plot_experiment(name, rows, out / f"{name}.png")
    print_table(name, rows)
    print(f"wrote {out / name}.csv and {out / name}.png")
    return rows


def print_table(name: str, rows: list[dict[str, Any]]) -> None:
    show = [r for r in rows if r["sigma"] in (0.0, 1.0, 2.0)] if name in ("methods", "layouts", "literal") else rows
    extra = [k for k in ("mean_parallel_deg", "mean_perpendicular_deg") if k in rows[0]]
    print(f"{'method':<13}{'layout':<20}{'sigma':>6}{'views':>6}{'fail':>6}{'mean_fu':>10}{'std_fu':>9}"
          f"{'mean_fv':>10}{'std_fv':>9}{'std_u0':>9}{'std_v0':>9}{'std_s':>9}" + "".join(f"{k:>24}" for k in extra))
    for r in show:
        print(f"{r['method']:<13}{r['layout']:<20}{r['sigma']:>6.2f}{r['n_views']:>6}{r['failures']:>6}"
              f"{r['mean_fu']:>10.2f}{r['std_fu']:>9.3f}{r['mean_fv']:>10.2f}{r['std_fv']:>9.3f}"
              f"{r['std_u0']:>9.3f}{r['std_v0']:>9.3f}{r['std_s']:>9.3f}" + "".join(f"{r[k]:>24.3f}" for k in extra))
