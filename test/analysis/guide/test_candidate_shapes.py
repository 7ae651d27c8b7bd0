"""A candidate's circles must image as the ellipses the detector accepts (analysis/guide/candidate_shapes.py,
the shape rule of analysis/guide/candidates.py): exact ellipses under a pinhole, bent beyond the detector's
tests near the border of a wide lens with strong barrel distortion, where the detector measures a single
ring along its traced contour (up to a limit) and refuses a grid's elements."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidate_shapes import contour_scale, shape_circles, shape_shares
from pascal_calib_ros.analysis.guide.candidates import (
    RING_SHAPE_SHARE,
    SHAPE_SHARE,
    Feasibility,
    Placement,
    default_feasibility,
    feasibility_problem,
    place,
)
from pascal_calib_ros.detect.detection import DetectionParams
from pascal_calib_ros.detect.target_detector import BENT_OUTLINE, detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.targets import resolve_target

# 1280x720, f = 640 px (90 degrees across the width), k1 = -0.28: the wide case of the guided study
WIDE = Camera.from_params(640.0, 641.6, 654.1, 353.5, dist=[-0.28, 0.0392, -0.0008, 0.0005, 0.0], width=1280,
                          height=720)
PINHOLE = Camera.from_params(640.0, 641.6, 654.1, 353.5, width=1280, height=720)
BORDER = Placement((1152.0, 264.0), 0.32, 0.0, 0.0, 0.0)  # a ring 330 px tall, 38 px from the right border
CLOSE = Placement((384.0, 264.0), 0.16, 45.0, 180.0, 0.0)  # 570 px across, tilted 45 degrees, 95 px inside
CENTRE = Placement((640.0, 360.0), 0.32, 25.0, 90.0, 0.0)


def _shares(cam: Camera, *ps: Placement) -> np.ndarray:
    ring = resolve_target("ring_a4")
    T = [place(ring, cam, p) for p in ps]
    return shape_shares(ring, cam, np.stack([t.R for t in T]), np.stack([t.translation for t in T]))


def test_a_pinhole_images_circles_as_ellipses_whatever_the_pose() -> None:
    assert np.all(_shares(PINHOLE, BORDER, CLOSE, CENTRE) < 0.02)


def test_barrel_distortion_bends_a_ring_near_the_border_or_close_beyond_the_detectors_limits() -> None:
    border, close, centre = _shares(WIDE, BORDER, CLOSE, CENTRE)
    assert border > 1.0 and close > 1.0
    assert centre < 0.2


def test_a_ring_past_the_shape_limit_is_still_measured_on_renders() -> None:
    """The share is against the ellipse tests (a share above 1: the ring's image is no conic); the
    detector measures such a ring along its traced contour (detect/contour_edges.py, issue 36),
    the guide keeps its candidates below the limits anyway (feasibility, below), where the
    ellipse path measures them. Both views measured, every point within 0.3 px of the truth."""
    ring = resolve_target("ring_a4")
    params = DetectionParams.for_lens(False, gamma=SensorModel().gamma)  # detected as the renders' gamma
    for p in (BORDER, CENTRE):
        T = place(ring, WIDE, p)
        img = render_view(ring, WIDE, Pose(T.R, T.translation), SensorModel(blur_sigma=1.0, seed=3)).image
        det = detect_target(img, ring, params)
        assert det.ok, det.reason
        for e in det.edges:  # each edge point on its circle's true image: undistorted, on the conic
            r = ring.circles[e.circle]
            rays = WIDE.unproject(e.points)
            X = rays * (T.translation @ T.R[:, 2] / (rays @ T.R[:, 2]))[:, None]  # on the target's plane
            local = (X - T.translation) @ T.R
            off = np.abs(np.hypot(local[:, 0] - r.center[0], local[:, 1] - r.center[1]) - r.radius)
            px = off * WIDE.K[0, 0] / np.linalg.norm(X, axis=1)  # metres on the sheet -> pixels, roughly
            assert np.median(px) < 0.05 and px.max() < 0.3, (p, np.median(px), px.max())


def test_feasibility_refuses_a_bent_ring_and_says_why() -> None:
    """A single ring is measured along its traced contour up to BENT_OUTLINE times the ellipse
    tests' limits: the guide offers it up to the same share of that (RING_SHAPE_SHARE); a grid's
    elements have no such path and keep SHAPE_SHARE of the ellipse limits."""
    ring = resolve_target("ring_a4")
    rules = default_feasibility(ring, WIDE.width)
    assert rules.shape_share == RING_SHAPE_SHARE == SHAPE_SHARE * BENT_OUTLINE
    assert default_feasibility(resolve_target("ring_grid_a4"), WIDE.width).shape_share == SHAPE_SHARE
    # BORDER and CLOSE are past the ellipse tests (shares 1.0-1.1) but within the ring's share
    assert feasibility_problem(ring, WIDE, place(ring, WIDE, BORDER), rules) == ""
    assert feasibility_problem(ring, WIDE, place(ring, WIDE, CLOSE), rules) == ""
    tight = replace(rules, shape_share=SHAPE_SHARE)
    assert "not ellipses the detector accepts" in feasibility_problem(ring, WIDE, place(ring, WIDE, BORDER), tight)
    assert feasibility_problem(ring, WIDE, place(ring, WIDE, CENTRE), tight) == ""
    unchecked = replace(rules, shape_share=np.inf)
    assert feasibility_problem(ring, WIDE, place(ring, WIDE, BORDER), unchecked) == ""
    assert Feasibility().shape_share < 1.0  # a margin below the detector's limit


def test_a_view_behind_the_camera_has_no_shape() -> None:
    ring = resolve_target("ring_a4")
    T = place(ring, PINHOLE, CENTRE)
    t = T.translation * np.array([1.0, 1.0, -1.0])
    assert shape_shares(ring, PINHOLE, T.R[None], t[None])[0] == np.inf


def test_contour_scale_follows_the_detectors_downscaling() -> None:
    params = DetectionParams()
    assert contour_scale(ImageSize(1280, 720), params) == 1
    assert contour_scale(ImageSize(1600, 1200), params) == 2
    assert contour_scale(ImageSize(2592, 1944), params) == 4


@pytest.mark.parametrize(("name", "kinds"), [("ring_a4", [0, 1]), ("ring_grid_a4", [3, 1] * 4)])
def test_the_circles_checked(name: str, kinds: list[int]) -> None:
    ctr, rad, kind, pairs = shape_circles(resolve_target(name))
    assert kind.tolist() == kinds
    assert len(ctr) == len(rad) == len(kinds)
    assert pairs == ([(0, 1)] if name == "ring_a4" else [])


def test_the_batched_concentric_spread_is_the_detectors() -> None:
    from pascal_calib_ros.analysis.guide.candidate_shapes import concentric_spreads
    from pascal_calib_ros.detect.grids import concentric_fit
    from pascal_calib_ros.geometry.conic import Ellipse

    rng = np.random.default_rng(4)
    outer = np.c_[rng.uniform(100, 500, (20, 2)), rng.uniform(60, 120, 20), rng.uniform(30, 60, 20),
                  rng.uniform(-3, 3, 20)]
    hole = np.c_[outer[:, :2] + rng.normal(0, 5, (20, 2)), outer[:, 2:4] * rng.uniform(0.4, 0.6, (20, 1)),
                 outer[:, 4] + rng.normal(0, 0.2, 20)]
    want = [concentric_fit(Ellipse(*o), Ellipse(*h))[0] for o, h in zip(outer, hole, strict=True)]
    assert np.allclose(concentric_spreads(outer, hole), want, rtol=1e-9, atol=1e-12)
