import json
from pathlib import Path

import numpy as np

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.sim.render import Pose, SensorModel, features_in_image, render_view, write_view
from pascal_calib_ros.targets import Target


def test_render_is_exact_where_no_blur(ring_target: Target) -> None:
    """Without blur/gamma/noise a pixel's grey level is its area coverage: pixels far inside the
    annulus are black, far outside white, and the mean over the image matches the annulus area."""
    cam = Camera.from_params(600, 600, 320, 240, width=640, height=480)
    pose = Pose(np.eye(3), np.array([-0.1485, -0.105, 0.6]))
    v = render_view(ring_target, cam, pose, SensorModel(blur_sigma=0, noise_sigma=0, gamma=1.0, vignetting=0,
                                                        background_texture=0))
    img = v.image.astype(float) / 255
    # the ring centre projects to the principal point; radii 0.08 / 0.6 * 600 = 80 px, 40 px
    yy, xx = np.mgrid[0:480, 0:640]
    r = np.hypot(xx - 320, yy - 240)
    assert np.all(np.abs(img[(r > 42) & (r < 78)] - 0.06) < 0.003)
    assert np.all(np.abs(img[(r > 82) & (r < 100)] - 0.85) < 0.003)
    dark = np.sum((0.85 - img[r < 100]) / (0.85 - 0.06))
    assert abs(dark - np.pi * (80**2 - 40**2)) < 0.002 * np.pi * (80**2 - 40**2)


def test_ground_truth_is_written_beside_the_image(tmp_path: Path, ring_target: Target) -> None:
    cam = Camera.from_params(500, 500, 160, 120, dist=[-0.1, 0, 0, 0, 0], width=320, height=240)
    pose = Pose(np.eye(3), np.array([-0.1485, -0.105, 0.9]))
    p = write_view(render_view(ring_target, cam, pose), tmp_path / "v.png")
    gt = json.loads(p.with_suffix(".json").read_text())
    assert gt["width"] == 320 and gt["D"][0] == -0.1 and gt["pose"]["t"][2] == 0.9
    assert features_in_image(ring_target, cam, pose)
    assert not features_in_image(ring_target, cam, Pose(np.eye(3), np.array([0.1, -0.105, 0.9])))
