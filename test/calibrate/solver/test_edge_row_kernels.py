"""The compiled edge rows (calibrate/solver/edge_row_kernels.py) against the numpy path of
:class:`~pascal_calib_ros.calibrate.solver.problem.Problem` they replace for a flat target and a polynomial
lens: residuals, rays and Jacobian, and the Jacobian against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from jacobians import numeric_jacobian

from pascal_calib_ros.calibrate.solver.observations import ViewData
from pascal_calib_ros.calibrate.solver.problem import Problem
from pascal_calib_ros.geometry.camera import Camera, rodrigues
from pascal_calib_ros.geometry.lens import DISTORTION_CHOICES

D8 = [-0.2, 0.05, 0.001, -0.002, 0.01, 0.03, -0.01, 0.002]
GRID = np.array([(0.03 * i, 0.03 * j) for i in range(5) for j in range(4)])


def _views(model: str, dof: int, seed: int) -> tuple[list[ViewData], list[np.ndarray], np.ndarray]:
    """Three noisy views of rings (both edges) or of a single ring (dof 5), with three corners each."""
    lens = DISTORTION_CHOICES[model][0]
    D = np.array(D8[: lens.n])
    cam = Camera(np.array([[600.0, 0.7, 322.0], [0.0, 610.0, 238.0], [0, 0, 1]]), D, 640, 480, lens.name)
    rng = np.random.default_rng(seed)
    centres = GRID if dof == 6 else GRID[:1]
    views, poses = [], []
    for _ in range(3):
        rv = np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.5, 0.5) if dof == 6 else 0.0]
        t = np.r_[rng.uniform(-0.08, -0.03), rng.uniform(-0.06, -0.02), rng.uniform(0.3, 0.4)]
        R = rodrigues(rv)
        th = np.linspace(0, 2 * np.pi, 20, endpoint=False)
        ctr = np.repeat(np.repeat(centres, len(th), 0), 2, 0)
        radii = np.tile([0.01, 0.006], len(centres) * len(th))
        ang = np.repeat(np.tile(th, len(centres)), 2)
        P = ctr + radii[:, None] * np.c_[np.cos(ang), np.sin(ang)]
        pts = cam.project(np.c_[P, np.zeros(len(P))] @ R.T + t) + rng.normal(0, 0.3, (len(P), 2))
        v = ViewData(pts, ctr, radii, np.tile([1.0, -1.0], len(P) // 2), np.zeros(len(P), int))
        v.corner_obj = np.array([[0.0, 0.0], [0.05, 0.02], [0.1, 0.08]])
        v.corners = cam.project(np.c_[v.corner_obj, np.zeros(3)] @ R.T + t) + 0.2
        views.append(v)
        poses.append(np.r_[rv[: dof - 3], t])
    intr0 = np.r_[600.0, 610.0, 322.0, 238.0, 0.7, D]
    return views, poses, intr0


def _problem(model: str, dof: int, offsets: bool, seed: int = 1) -> tuple[Problem, np.ndarray, np.ndarray]:
    lens, free_d = DISTORTION_CHOICES[model]
    views, poses, intr0 = _views(model, dof, seed)
    prob = Problem(views, dof, ("fx", "fy", "cx", "cy", "skew", *free_d), offsets, lens=lens)
    x = prob.pack(intr0 * (1 + 1e-3), poses, np.array([0.1, -0.2, 0.05]))
    return prob, x, intr0


@pytest.mark.parametrize("model", ["plumb_bob", "rational_polynomial"])
@pytest.mark.parametrize("dof", [6, 5])
@pytest.mark.parametrize("offsets", [True, False])
def test_compiled_rows_match_numpy(model: str, dof: int, offsets: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    prob, x, intr0 = _problem(model, dof, offsets)
    assert prob._compiled
    f, Jg, Jv = prob.evaluate(x, intr0)
    rays = prob._ray_cache[1].copy()  # type: ignore[index]
    numpy_prob, _, _ = _problem(model, dof, offsets)
    monkeypatch.setattr(Problem, "_compiled", property(lambda self: False))
    f0, Jg0, Jv0 = numpy_prob.evaluate(x, intr0)
    assert np.allclose(numpy_prob._ray_cache[1], rays, rtol=0, atol=1e-13)  # type: ignore[index]
    assert np.allclose(f, f0, rtol=0, atol=1e-10)
    for J, J0 in ((Jg, Jg0), (Jv, Jv0)):
        assert J.shape == J0.shape
        assert np.allclose(J, J0, rtol=1e-10, atol=1e-9 * np.abs(J0).max())


def test_compiled_jacobian_matches_finite_differences() -> None:
    prob, x, intr0 = _problem("rational_polynomial", 6, True, seed=3)
    _, Jg, Jv = prob.evaluate(x, intr0)
    J = prob.dense_jacobian(Jg, Jv)
    Jn = numeric_jacobian(lambda v: prob.residuals(v, intr0), x, 1e-6, 1e-3)
    rel = np.linalg.norm(J - Jn, axis=0) / np.maximum(np.linalg.norm(Jn, axis=0), 1e-12)
    assert np.all(rel < 2e-3), rel


def test_warped_target_and_fisheye_take_the_numpy_path() -> None:
    views, _, _ = _views("plumb_bob", 6, 2)
    assert not Problem(views, 6, ("fx",), True, shape=("warp_x",))._compiled
    assert not Problem(views, 6, ("fx",), True, lens=DISTORTION_CHOICES["equidistant"][0])._compiled


def test_rays_from_the_last_camera_are_the_rays_from_scratch() -> None:
    """The rays are found by Newton's method from the last camera's rays (an optimiser's next
    camera is near it): the same rays as from scratch."""
    prob, x, intr0 = _problem("rational_polynomial", 6, True)
    prob.evaluate(x, intr0, jac=False)
    x2 = x.copy()
    x2[:4] *= 1.01
    x2[5:9] += 0.02
    f = prob.evaluate(x2, intr0, jac=False)[0]
    fresh, _, _ = _problem("rational_polynomial", 6, True)
    assert np.allclose(fresh.evaluate(x2, intr0, jac=False)[0], f, rtol=0, atol=1e-11)
    assert np.allclose(fresh._ray_cache[1], prob._ray_cache[1], rtol=0, atol=1e-13)  # type: ignore[index]


def test_one_compiled_version_of_each_kernel() -> None:
    """numba compiles a kernel once per argument type: the problem passes one set of types, the
    one ``compile_all`` (make venv) builds, also from float32 observations."""
    from pascal_calib_ros.calibrate.solver import edge_row_kernels as K

    K.compile_all()
    views, poses, intr0 = _views("plumb_bob", 6, 4)
    for v in views:
        v.points, v.centers = v.points.astype(np.float32), v.centers.astype(np.float32)
        v.radii = v.radii.astype(np.float32)
    prob = Problem(views, 6, ("fx", "fy", "cx", "cy"), True)
    prob.evaluate(prob.pack(intr0, poses, np.zeros(3)), intr0)
    assert [len(k.signatures) for k in (K.edge_rays, K.edge_fit, K.edge_jacobian)] == [1, 1, 1]
