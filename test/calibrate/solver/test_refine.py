"""Joint refinement: the analytic Jacobian against finite differences, and recovery of the
intrinsics and of the printed target's shape from exact synthetic edge points."""

from __future__ import annotations

import numpy as np
import pytest
from jacobians import numeric_jacobian

from pascal_calib_ros.calibrate.solver.observations import ViewData
from pascal_calib_ros.calibrate.solver.problem import SHAPE_NAMES, Problem
from pascal_calib_ros.calibrate.solver.refine import refine
from pascal_calib_ros.geometry.camera import Camera, rodrigues

ALL_INTRINSICS = ("fx", "fy", "cx", "cy", "skew", "k1", "k2", "p1", "p2", "k3")
CAM = Camera.from_params(600.0, 610.0, 322.0, 238.0, 0.0, [-0.2, 0.05, 0.001, -0.002, 0.01], 640, 480)
GRID = np.array([(0.03 * i, 0.03 * j) for i in range(7) for j in range(5)])  # circle centres, metres
RADIUS = 0.01


def _printed(xy: np.ndarray, shape: np.ndarray, frame: tuple[float, float, float, float]) -> np.ndarray:
    """The model's printed sheet: y scaled by 1 + pitch_ratio, parabolic warp in z."""
    xm, ym, xh, yh = frame
    z = shape[1] * (1 - ((xy[:, 0] - xm) / xh) ** 2) + shape[2] * (1 - ((xy[:, 1] - ym) / yh) ** 2)
    return np.c_[xy[:, 0], xy[:, 1] * (1 + shape[0]), z]


def _views(n_views: int, dof: int, noise: float, seed: int, shape: np.ndarray | None = None,
           frame: tuple[float, float, float, float] = (0.09, 0.06, 0.09, 0.06)
           ) -> tuple[list[ViewData], list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    shape = np.zeros(3) if shape is None else shape
    views, poses = [], []
    centres = GRID if dof == 6 else GRID[:1]
    for _ in range(n_views):
        rv = np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.5, 0.5) if dof == 6 else 0.0]
        t = np.r_[rng.uniform(-0.12, -0.05), rng.uniform(-0.09, -0.03), rng.uniform(0.35, 0.45)]
        if dof == 5:
            t[:2] = rng.uniform(-0.03, 0.03, 2)
        R = rodrigues(rv)
        th = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ctr = np.repeat(centres, len(th), 0)
        nominal = ctr + RADIUS * np.c_[np.cos(np.tile(th, len(centres))), np.sin(np.tile(th, len(centres)))]
        P = _printed(nominal, shape, frame)  # every point on the bent sheet
        pts = CAM.project(P @ R.T + t) + rng.normal(0, noise, (len(P), 2))
        views.append(ViewData(pts, ctr, np.full(len(P), RADIUS), np.ones(len(P)), np.zeros(len(P), int)))
        poses.append(np.r_[rv[: dof - 3], t])
    return views, poses


@pytest.mark.parametrize("dof", [6, 5])
def test_analytic_jacobian_matches_finite_differences(dof: int) -> None:
    views, poses = _views(3, dof, noise=0.3, seed=dof)
    for v in views:  # checkerboard corners too
        v.corner_obj = np.array([[0.0, 0.0], [0.05, 0.02], [0.1, 0.08]])
        v.corners = CAM.project(np.c_[v.corner_obj, np.zeros(3)] @ np.eye(3).T + [0, 0, 0.4]) + 0.2
    prob = Problem(views, dof, ALL_INTRINSICS, True, shape=SHAPE_NAMES)
    intr0 = np.r_[600.0, 610.0, 322.0, 238.0, 0.5, CAM.D]
    x = prob.pack(intr0, poses, np.array([0.1, -0.2, 0.05]), np.array([0.002, 0.001, -0.0005]))
    _, Jg, Jv = prob.evaluate(x, intr0)
    J = prob.dense_jacobian(Jg, Jv)
    Jn = numeric_jacobian(lambda v: prob.residuals(v, intr0), x, 1e-6, 1e-3)
    rel = np.linalg.norm(J - Jn, axis=0) / np.maximum(np.linalg.norm(Jn, axis=0), 1e-12)
    assert np.all(rel < 2e-3), rel


def test_recovers_intrinsics_from_perturbed_start() -> None:
    views, poses = _views(8, 6, noise=0.05, seed=1)
    K0 = CAM.K.copy()
    K0[0, 0] *= 1.03
    K0[1, 1] *= 0.98
    K0[:2, 2] += [6.0, -5.0]
    res = refine(views, K0, np.zeros(5), poses, 6)
    assert res.success
    assert abs(res.K[0, 0] / CAM.K[0, 0] - 1) < 2e-4 and abs(res.K[1, 1] / CAM.K[1, 1] - 1) < 2e-4
    assert np.hypot(*(res.K[:2, 2] - CAM.K[:2, 2])) < 0.3
    assert res.rms < 0.08
    assert 0 < res.std["fx"] < 0.5


def test_target_shape_is_estimated_and_matters() -> None:
    frame = (0.09, 0.06, 0.09, 0.06)
    truth = np.array([0.004, 0.0015, -0.001])  # y printed 0.4 % long, 1.5 mm and -1 mm of warp
    views, poses = _views(12, 6, noise=0.05, seed=3, shape=truth, frame=frame)
    flat = refine(views, CAM.K, CAM.D, poses, 6)
    shaped = refine(views, CAM.K, CAM.D, poses, 6, shape=SHAPE_NAMES, shape_frame=frame)
    est = np.array([shaped.shape[n] for n in SHAPE_NAMES])
    assert np.allclose(est, truth, atol=[2e-4, 1e-4, 1e-4]), est
    assert all(0 < shaped.shape_std[n] < 1e-3 for n in SHAPE_NAMES)
    err = {name: abs(r.K[1, 1] / CAM.K[1, 1] - 1) for name, r in (("flat", flat), ("shaped", shaped))}
    assert err["shaped"] < 3e-4 < err["flat"], err  # ignoring the shape biases fy
    assert shaped.rms < 0.5 * flat.rms


def test_unknown_shape_parameter_is_an_error() -> None:
    views, poses = _views(3, 6, noise=0.1, seed=2)
    with pytest.raises(ValueError, match="shape"):
        refine(views, CAM.K, CAM.D, poses, 6, shape=("bulge",))


# -- checkerboard corners only (issue 22) ----------------------------------------------------
BOARD = np.array([(0.025 * i, 0.025 * j) for j in range(7) for i in range(10)]) - [0.1125, 0.075]


def _corner_views(n_views: int, noise: float, seed: int) -> tuple[list[ViewData], list[np.ndarray], list[np.ndarray]]:
    """Views with checkerboard corners and no edge points: (views, true poses, exact corners)."""
    rng = np.random.default_rng(seed)
    views, poses, exact = [], [], []
    for _ in range(n_views):
        rv = np.r_[rng.uniform(-0.6, 0.6, 2), rng.uniform(-0.3, 0.3)]
        t = np.r_[rng.uniform(-0.08, 0.08), rng.uniform(-0.06, 0.06), rng.uniform(0.45, 0.6)]
        q = CAM.project(np.c_[BOARD, np.zeros(len(BOARD))] @ rodrigues(rv).T + t)
        v = ViewData(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, int))
        v.corners, v.corner_obj = q + rng.normal(0, noise, q.shape), BOARD.copy()
        views.append(v)
        poses.append(np.r_[rv, t])
        exact.append(q)
    return views, poses, exact


def test_views_with_corners_only_are_refined() -> None:
    views, poses, _ = _corner_views(8, 0.05, seed=4)
    K0 = CAM.K * [[1.02, 1, 1], [1, 0.99, 1], [1, 1, 1]]
    res = refine(views, K0, np.zeros(5), poses, 6, use_offsets=False)
    assert res.success and res.covariance is not None
    assert abs(res.K[0, 0] - CAM.K[0, 0]) < 4 * res.std["fx"] < 2.0
    assert abs(res.K[0, 2] - CAM.K[0, 2]) < 4 * res.std["cx"] < 2.0
    assert 0.05 < res.rms < 0.09  # the corner reprojection RMS (a 2-vector's length: sqrt(2) x 0.05)
    assert np.all(res.view_rms > 0) and all(len(r) == 0 for r in res.residuals)


@pytest.mark.parametrize("loss_scale", [np.inf, 0.3])
def test_gross_corner_errors_are_rejected_and_counted(loss_scale: float) -> None:
    views, poses, _ = _corner_views(8, 0.1, seed=5)
    clean = refine(views, CAM.K, CAM.D, poses, 6, use_offsets=False, loss_scale=loss_scale)
    spoiled = [ViewData(v.points, v.centers, v.radii, v.signs, v.circle_ids, v.corners.copy(), v.corner_obj)
               for v in views]
    spoiled[2].corners[[5, 17, 30]] += [[2.5, -1.0], [-1.8, 2.0], [0.0, 3.0]]  # three misdetected corners
    spoiled[6].corners[40] += [1.5, 1.5]
    kept = refine(spoiled, CAM.K, CAM.D, poses, 6, use_offsets=False, loss_scale=loss_scale, outlier_k=0.0)
    trimmed = refine(spoiled, CAM.K, CAM.D, poses, 6, use_offsets=False, loss_scale=loss_scale)
    assert [v.rejected_corners for v in trimmed.views] == [0, 0, 3, 0, 0, 0, 1, 0]
    assert len(trimmed.views[2].corners) == len(BOARD) - 3 and len(trimmed.corner_residuals[2]) == len(BOARD) - 3
    # rejected, the bad corners leave the solution and its noise estimate as if they had never been there
    for k in ("fx", "cx"):
        assert abs(trimmed.K[0, 0 if k == "fx" else 2] - clean.K[0, 0 if k == "fx" else 2]) < 0.2 * clean.std[k]
    assert abs(trimmed.std["fx"] / clean.std["fx"] - 1) < 0.05 and trimmed.rms < 1.01 * clean.rms
    assert kept.rms > 1.5 * clean.rms
    if not np.isfinite(loss_scale):  # least squares: kept, they pull cx by almost 2 sigma and inflate sigma
        assert abs(kept.K[0, 2] - clean.K[0, 2]) > 1.5 * clean.std["cx"] and kept.std["fx"] > 1.4 * clean.std["fx"]
