"""Synthetic views (analysis/guide/view_synthesis.py): many poses at once give what each pose gives
alone, and the points lie on their circles' images."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidates import Placement, place_all
from pascal_calib_ros.analysis.guide.view_ranking import distinct, distinct_from_all
from pascal_calib_ros.analysis.guide.view_synthesis import synthesise_view, synthesise_views
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.targets import resolve_target

CAM = Camera(np.array([[620.0, 0.0, 330.0], [0.0, 615.0, 236.0], [0, 0, 1]]), np.array([-0.2, 0.05, 0.0, 0.0, 0.0]),
             640, 480)


def _poses(target_name: str) -> tuple[object, np.ndarray, np.ndarray]:
    target = resolve_target(target_name)
    placements = [Placement((320.0 + 60 * k, 240.0 - 30 * k), 0.45 + 0.05 * k, 30.0 * (k % 2), 60.0 * k, 20.0 * k)
                  for k in range(-2, 3)]
    o = np.array(target.circles[0].center)
    poses = place_all(target, CAM, placements)
    R = np.stack([p.R for p in poses])
    t = np.stack([p.translation + p.R @ np.r_[o, 0.0] for p in poses])  # the local frame's origin
    return target, R, t


@pytest.mark.parametrize("name,coarse", [("ring_grid_a4", False), ("ring_grid_a4", True), ("pascal_board_a3", False)])
def test_many_poses_give_what_each_pose_gives_alone(name: str, coarse: bool) -> None:
    target, R, t = _poses(name)
    args = (24, 12) if coarse else (0, 0)
    batch = synthesise_views(target, CAM, R, t, max_points=args[0], max_elements=args[1])  # type: ignore[arg-type]
    for k, sv in enumerate(batch):
        one = synthesise_view(target, CAM, R[k], t[k], max_points=args[0], max_elements=args[1])  # type: ignore[arg-type]
        assert len(sv.data.points) == len(one.data.points) > 0
        assert np.allclose(sv.data.points, one.data.points, rtol=0, atol=1e-9)
        assert np.array_equal(sv.data.circle_ids, one.data.circle_ids)
        assert np.allclose(sv.weight, one.weight) and np.allclose(sv.data.corners, one.data.corners, atol=1e-9)


def test_points_lie_on_their_circles() -> None:
    """Each point's ray meets the target plane at its circle's radius from its centre."""
    target, R, t = _poses("ring_grid_a4")
    for k, sv in enumerate(synthesise_views(target, CAM, R, t)):  # type: ignore[arg-type]
        rays = CAM.unproject(sv.data.points)
        n = R[k][:, 2]
        X = rays * (n @ t[k] / (rays @ n))[:, None]
        local = (X - t[k]) @ R[k]
        assert np.allclose(np.hypot(*(local[:, :2] - sv.data.centers).T), sv.data.radii, rtol=1e-7)


def test_distinct_from_all_is_distinct_pairwise() -> None:
    rng = np.random.default_rng(2)

    def random(n: int) -> list[Placement]:
        return [Placement((float(rng.uniform(0, 640)), float(rng.uniform(0, 480))), float(rng.uniform(0.3, 0.8)),
                          float(rng.uniform(0, 45)), float(rng.uniform(0, 360)), float(rng.uniform(-180, 180)))
                for _ in range(n)]

    a, b = random(200), random(6)
    for roll in (0.0, 20.0):
        got = distinct_from_all(a, b, ImageSize(640, 480), roll)
        want = [all(distinct(p, q, ImageSize(640, 480), roll) for q in b) for p in a]
        assert got.tolist() == want
        assert 0 < sum(want) < len(want)
