"""Feasibility of candidate views (analysis/guide/candidates.py): the whole target in the image with a
margin, the tilt measured against the line of sight, a distance range, features large enough."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidates import (
    Feasibility,
    Placement,
    default_feasibility,
    distance_for_size,
    feasibility_problem,
    line_of_sight_tilt_deg,
    max_tilt_deg,
    place,
)
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.targets import Target, resolve_target

# a wide pinhole camera: its image corners are ~40 degrees off the optical axis
CAM = Camera.from_params(400.0, 400.0, 320.0, 240.0, width=640, height=480)


def test_place_puts_the_features_centre_on_the_pixel_at_the_tilt_against_the_line_of_sight(ring_target: Target) -> None:
    p = Placement((120.0, 90.0), distance_for_size(ring_target, CAM, 0.3), 35.0, 60.0, 10.0)
    T = place(ring_target, CAM, p)
    c = np.r_[ring_target.rings[0].center, 0.0]
    assert np.allclose(CAM.project(T.apply(c)[None])[0], p.pixel, atol=1e-6)
    assert line_of_sight_tilt_deg(ring_target, T) == pytest.approx(35.0, abs=1e-6)
    assert np.linalg.norm(T.apply(c)) == pytest.approx(p.distance)


def test_target_leaving_the_image_is_rejected(ring_target: Target) -> None:
    rules = default_feasibility(ring_target, CAM.width)
    d = distance_for_size(ring_target, CAM, 0.3)
    inside = place(ring_target, CAM, Placement((320.0, 240.0), d, 20.0, 0.0, 0.0))
    assert feasibility_problem(ring_target, CAM, inside, rules) == ""
    cut = place(ring_target, CAM, Placement((20.0, 240.0), d, 20.0, 0.0, 0.0))
    assert "leaves the image" in feasibility_problem(ring_target, CAM, cut, rules)
    # a margin is kept: the same view shifted until its edge is 2 px from the border is refused
    behind = Transform.from_rt(np.eye(3), [0.0, 0.0, -0.5])
    assert "leaves the image" in feasibility_problem(ring_target, CAM, behind, rules)


def test_tilt_is_measured_against_the_line_of_sight_not_the_optical_axis(ring_target: Target) -> None:
    """Near the border a sheet square to the optical axis is tilted ~35 degrees against its line
    of sight; one facing the camera along the line of sight is not tilted at all."""
    rules = Feasibility(margin_px=5.0, max_tilt_deg=25.0, min_radius_px=4.0)
    pixel = (540.0, 390.0)
    d = distance_for_size(ring_target, CAM, 0.15)
    facing = place(ring_target, CAM, Placement(pixel, d, 0.0, 0.0, 0.0))
    assert feasibility_problem(ring_target, CAM, facing, rules) == ""
    ray = CAM.unproject(np.array([pixel]))[0]
    c = np.r_[ring_target.rings[0].center, 0.0]
    square = Transform.from_rt(np.eye(3), d * ray - c)  # the sheet's normal along the optical axis
    tilt = line_of_sight_tilt_deg(ring_target, square)
    assert tilt == pytest.approx(np.degrees(np.arccos(ray[2])), abs=1e-6)
    assert tilt > 30
    assert "against the line of sight" in feasibility_problem(ring_target, CAM, square, rules)
    # and a sheet tilted beyond the detector's limit for the target
    steep = place(ring_target, CAM, Placement((320.0, 240.0), d, max_tilt_deg(ring_target) + 5, 0.0, 0.0))
    assert "against the line of sight" in feasibility_problem(ring_target, CAM, steep,
                                                              default_feasibility(ring_target, CAM.width))


def test_back_of_the_sheet_and_distance_and_size(ring_target: Target) -> None:
    d = distance_for_size(ring_target, CAM, 0.3)
    back = place(ring_target, CAM, Placement((320.0, 240.0), d, 170.0, 0.0, 0.0))
    assert "line of sight" in feasibility_problem(ring_target, CAM, back, Feasibility(max_tilt_deg=89.0))
    rules = Feasibility(min_distance=0.5 * d, max_distance=0.9 * d)
    T = place(ring_target, CAM, Placement((320.0, 240.0), d, 0.0, 0.0, 0.0))
    assert "distance" in feasibility_problem(ring_target, CAM, T, rules)
    grid = resolve_target("ring_grid_a4")
    far = place(grid, CAM, Placement((320.0, 240.0), distance_for_size(grid, CAM, 0.12), 0.0, 0.0, 0.0))
    assert "too small" in feasibility_problem(grid, CAM, far, default_feasibility(grid, CAM.width))
