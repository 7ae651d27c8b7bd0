"""Shared fixtures: small synthetic sessions rendered once per test run."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.detect.rings import Detection, detect_target
from pascal_calib_ros.geometry.camera import Camera, rodrigues
from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import Target, resolve_target


@pytest.fixture(scope="session")
def ring_target() -> Target:
    return resolve_target("ring_a4")


@pytest.fixture(scope="session")
def board_target() -> Target:
    return resolve_target("pascal_board_a3")


def _session(target: Target, spec: SessionSpec) -> tuple[Camera, list[np.ndarray], list[Detection]]:
    cam, views = render_session_views(target, spec)
    imgs = [v.image for v in views]
    dets = [detect_target(im, target, name=str(v.meta["name"])) for im, v in zip(imgs, views, strict=True)]
    return cam, imgs, dets


@pytest.fixture(scope="session")
def ring_session(ring_target: Target) -> tuple[Camera, list[np.ndarray], list[Detection]]:
    """10 realistic views (blur, gamma 2.2, noise, vignetting), no distortion, 800x600."""
    return _session(ring_target, SessionSpec(width=800, height=600, views=10, seed=5))


@pytest.fixture(scope="session")
def ring_session_distorted(ring_target: Target) -> tuple[Camera, list[np.ndarray], list[Detection]]:
    """10 realistic views with strong barrel distortion (k1 = -0.3) and JPEG, 800x600."""
    return _session(ring_target, SessionSpec(width=800, height=600, views=10, k1=-0.3, jpeg=92, blur=1.3, seed=6))


@pytest.fixture(scope="session")
def board_session(board_target: Target) -> tuple[Camera, list[np.ndarray], list[Detection]]:
    return _session(board_target, SessionSpec(width=1024, height=768, views=8, k1=-0.1, seed=7,
                                              size_range=(0.5, 0.8)))


def homography(K: np.ndarray, rvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    R = rodrigues(rvec)
    return K @ np.column_stack([R[:, 0], R[:, 1], t])


def random_plane_poses(n: int, seed: int, tilt: float = 0.5) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=3) * tilt, np.array([rng.normal() * 0.05, rng.normal() * 0.05, 1.0])) for _ in range(n)]
