"""Cameras and a grid of points shared by the export tests (test_opencv_storage, test_mrcal_model,
test_refit, ...)."""

from __future__ import annotations

import numpy as np

from pascal_calib_ros.geometry.camera import Camera

PLUMB = Camera.from_params(812.25, 815.5, 401.3, 297.7, dist=[-0.21, 0.07, 0.0008, -0.0005, -0.02], width=800,
                           height=600)
RATIONAL = Camera.from_params(550.0, 551.5, 400.3, 300.1, dist=[0.4, -0.1, 0.0005, -0.0003, 0.01, 0.65, -0.05, 0.002],
                              width=800, height=600, model="rational_polynomial")
FISHEYE = Camera.from_params(190.0, 190.4, 321.0, 239.5, dist=[0.02, -0.005, 0.001, -0.0002], width=640, height=480,
                             model="equidistant")


def grid_points(cam: Camera, step: float = 10.0) -> np.ndarray:
    """Camera-frame points (N, 3) behind a grid of pixels over the whole image, at 1.7 m, in front
    of the camera (OpenCV's fisheye takes the angle as atan(r), so rays at or beyond 90 degrees
    are left out)."""
    us, vs = np.meshgrid(np.arange(0.0, cam.width + 1e-9, step), np.arange(0.0, cam.height + 1e-9, step))
    rays = cam.unproject(np.stack([us.ravel(), vs.ravel()], 1))
    rays = rays[np.all(np.isfinite(rays), 1) & (rays[:, 2] > 0.05)]
    return 1.7 * rays


