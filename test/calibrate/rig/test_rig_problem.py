"""The joint rig problem: its Jacobian (the cameras' own Problem blocks chained through the pose
composition) against central differences of its residuals."""

import numpy as np
from jacobians import numeric_jacobian

from pascal_calib_ros.calibrate.rig.problem import RigProblem
from pascal_calib_ros.calibrate.solver.observations import ViewData
from pascal_calib_ros.calibrate.solver.problem import Problem
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.sim.rig import stereo_pair
from pascal_calib_ros.targets import resolve_target


def _views(cam, poses: list[Transform], n_circles: int = 6) -> list[ViewData]:
    """Exact edge points of the first circles of the ring grid (local frame) for each pose."""
    grid = resolve_target("ring_grid_a4")
    o = np.array(grid.circles[0].center)
    out = []
    th = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    for T in poses:
        pts, ctr, rad, sgn, ids = [], [], [], [], []
        for k, c in enumerate(grid.circles[:n_circles]):
            loc = np.array(c.center) - o
            P = np.c_[loc[0] + c.radius * np.cos(th), loc[1] + c.radius * np.sin(th), np.zeros(len(th))]
            pts.append(cam.project(T.apply(P)))
            ctr.append(np.tile(loc, (len(th), 1)))
            rad.append(np.full(len(th), c.radius))
            sgn.append(np.full(len(th), 1.0 if c.dark_inside else -1.0))
            ids.append(np.full(len(th), k))
        out.append(ViewData(np.concatenate(pts), np.concatenate(ctr), np.concatenate(rad), np.concatenate(sgn),
                            np.concatenate(ids)))
    return out


def test_rig_jacobian_matches_central_differences() -> None:
    left, right = stereo_pair(640, 480)
    E = right.pose.inverse()
    shots = [Transform.from_rotvec([0.2, -0.1, 0.05], [-0.08, -0.05, 0.6]),
             Transform.from_rotvec([-0.3, 0.2, 0.4], [-0.05, -0.02, 0.7]),
             Transform.from_rotvec([0.1, 0.35, -0.2], [-0.1, -0.06, 0.65])]
    free = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    views_l = _views(left.camera, shots)
    views_r = _views(right.camera, [E @ s for s in shots[1:]])  # the right camera saw shots 1 and 2
    subs = [Problem(views_l, 6, free, True), Problem(views_r, 6, free, True)]
    prob = RigProblem(subs, [np.array([0, 1, 2]), np.array([1, 2])], 3)
    intr = [np.r_[c.camera.K[0, 0], c.camera.K[1, 1], c.camera.K[0, 2], c.camera.K[1, 2], 0.0, c.camera.D]
            for c in (left, right)]
    ext = np.zeros((2, 6))
    ext[1] = np.r_[E.rotvec, E.translation]
    sp = np.array([np.r_[s.rotvec, s.translation] for s in shots])
    x = prob.pack(intr, ext, sp, [np.array([0.01, -0.02, 0.03]), np.array([0.02, -0.01])])
    # near the truth, where the edge residuals' analytic Jacobian (exact at the foot point) is sharp
    x += np.random.default_rng(0).normal(size=len(x)) * 1e-6 * np.maximum(np.abs(x), 1e-2)
    intr0 = np.concatenate(intr)
    f, Jg, Jv = prob.evaluate(x, intr0)
    assert len(f) == sum(len(v.points) for v in views_l + views_r)
    J = prob.dense_jacobian(Jg, Jv)
    assert J.shape == (len(f), prob.size) == (len(f), 18 + 6 + 3 * 6 + 5)
    num = numeric_jacobian(lambda v: prob.residuals(v, intr0), x, 1e-5, 1e-1)
    rel = np.linalg.norm(J - num, axis=0) / np.maximum(np.linalg.norm(num, axis=0), 1e-12)
    assert np.all(rel < 2e-4), [(k, r) for k, r in enumerate(rel) if r >= 2e-4]
    # the normal equations assembled shot by shot are J^T W J and J^T W f
    w = np.random.default_rng(1).uniform(0.5, 1.0, len(f))
    A, g = prob.normal_equations(f, Jg, Jv, w)
    assert np.allclose(A, J.T @ (J * w[:, None]), rtol=1e-10, atol=1e-8)
    assert np.allclose(g, J.T @ (w * f), rtol=1e-10, atol=1e-8)
    # unpack inverts pack
    i2, e2, s2, o2 = prob.unpack(x, intr0)
    assert np.allclose(prob.pack(i2, e2, s2, o2), x)
