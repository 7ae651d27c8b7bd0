"""mrcal as a judge (tools/mrcal_judge.py through tools/mrcal_bridge.py) on a rendered checkerboard
session with known truth: mrcal's calibration is near the truth, mrcal's projection uncertainty
equals ours when both propagate the same noise from the same observations, and a .cameramodel
projects as our camera does. Skipped, with the reason, where .venv-mrcal cannot run (no Python
3.12/3.13: `make mrcal-venv`)."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from pascal_calib_ros.analysis.statistics.uncertainty import projection_uncertainty
from pascal_calib_ros.calibrate.solver.lm import levenberg_marquardt
from pascal_calib_ros.calibrate.solver.observations import ViewData
from pascal_calib_ros.calibrate.solver.problem import Problem, camera_from_intrinsics
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import resolve_target

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import mrcal_bridge

from pascal_calib_ros.geometry import ImageSize

OK, WHY = mrcal_bridge.available()
pytestmark = pytest.mark.skipif(not OK, reason=WHY)

W, H = 800, 600
PLUMB_BOB_FREE = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
LS_SCALE = 100.0  # px: a soft-L1 scale this far above the residuals is least squares (weights 1 - 1e-8)


@pytest.fixture(scope="module")
def session() -> tuple[Camera, np.ndarray, list[np.ndarray]]:
    """checkerboard_a4, 800x600, 12 views with barrel distortion: (truth, object points (N, 3) m,
    per view the corners our detector found (N, 2))."""
    target = resolve_target("checkerboard_a4")
    cam, views = render_session_views(target, SessionSpec(width=W, height=H, views=12, k1=-0.15, seed=11))
    corners = [detect_target(v.image, target).corners for v in views]
    assert all(c is not None for c in corners), "the detector lost a board on the renders"
    assert target.checkerboard is not None
    xy = target.checkerboard.corner_points()
    return cam, np.c_[xy, np.zeros(len(xy))], [np.asarray(c, float) for c in corners]


def test_mrcal_calibration_is_near_the_truth_within_its_own_sigma(session) -> None:
    truth, obj, corners = session
    grid = np.stack(np.meshgrid(np.arange(20.0, W, 40.0), np.arange(20.0, H, 40.0)), -1).reshape(-1, 2)
    ans = mrcal_bridge.calibrate(corners, obj, (W, H), focal=0.85 * truth.K[0, 0], grid=grid)
    K, std = mrcal_bridge.K_of(ans["intrinsics"]), ans["std"]
    for name, est, true in (("fx", K[0, 0], truth.K[0, 0]), ("fy", K[1, 1], truth.K[1, 1]),
                            ("cx", K[0, 2], truth.K[0, 2]), ("cy", K[1, 2], truth.K[1, 2])):
        assert 0 < std[name] < 1.0, (name, std[name])
        assert abs(est - true) < 4 * std[name], f"{name}: {est:.3f} vs truth {true:.3f}, sigma {std[name]:.3f}"
    assert abs(ans["intrinsics"]["D"][0] - truth.D[0]) < 4 * std["D"][0]
    assert ans["distortion_model"] == "plumb_bob" and len(ans["intrinsics"]["D"]) == 5
    # clean renders: a noise of a hundredth of a pixel, so mrcal's threshold (a few times that noise)
    # may drop some corners of the most tilted views, whose true error reaches 0.07 px: a few per cent
    n_corners = sum(len(c) for c in corners)
    assert ans["n_outliers"] <= 0.03 * n_corners and len(ans["outliers_per_view"]) == len(corners)
    assert 0.005 < ans["noise_px"] < 0.1
    assert np.all(np.isfinite(ans["sigma_at_distance"])) and np.all(np.isfinite(ans["sigma_at_infinity"]))
    assert 0.3 < ans["distance_m"] < 1.5


def _our_least_squares(obj: np.ndarray, corners: list[np.ndarray]):
    """Our refinement problem on the corners alone (plumb_bob, zero skew), solved as least squares
    from OpenCV's calibrateCamera: (problem, solution, start intrinsics)."""
    _, K, D, rvecs, tvecs = cv2.calibrateCamera([obj.astype(np.float32)] * len(corners),
                                                [c.astype(np.float32) for c in corners], (W, H), None, None)
    views = [ViewData(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, int), corners=c,
                      corner_obj=obj[:, :2]) for c in corners]
    prob = Problem(views, 6, PLUMB_BOB_FREE, False, LS_SCALE)
    intr0 = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], 0.0, *np.ravel(D)[:5]])
    x0 = prob.pack(intr0, [np.r_[r.ravel(), t.ravel()] for r, t in zip(rvecs, tvecs, strict=True)],
                   np.zeros(len(corners)))
    sol = levenberg_marquardt(prob, x0, intr0, LS_SCALE, max_iter=100)
    assert sol.success, sol.message
    return prob, sol, intr0


def test_uncertainty_equals_ours_for_the_same_observations_and_noise(session) -> None:
    """Propagation alone: both solve the same least squares on the same corners, both propagate
    an observation noise of 0.2 px per coordinate (covariance sigma^2 (J^T J)^-1); the worst-direction
    projection sigma over the image, at the views' median distance and at infinity, must agree."""
    _, obj, corners = session
    prob, sol, intr0 = _our_least_squares(obj, corners)
    noise = 0.2
    cov = noise**2 * np.linalg.pinv(sol.normal_matrix)

    def camera_of(x: np.ndarray) -> Camera:
        return Camera(*camera_from_intrinsics(prob.unpack(x, intr0)[0]), W, H, "plumb_bob")

    def view_poses_of(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R, _, t = prob.rotations(prob.unpack(x, intr0)[2])
        return R, t

    distance = float(np.median(np.linalg.norm(view_poses_of(sol.x)[1], axis=1)))
    ours = projection_uncertainty(camera_of, view_poses_of, sol.x, cov, ImageSize(W, H), distance)
    ours_inf = projection_uncertainty(camera_of, view_poses_of, sol.x, cov, ImageSize(W, H), 1e9)  # infinity, to 1e-9
    ans = mrcal_bridge.uncertainty(corners, obj, (W, H), grid=ours.pixels, distance=distance, noise=noise,
                                   focal=700.0)
    # the same optimum (the two solvers stop within 1e-4 px of each other in a flat valley)
    intr = prob.unpack(sol.x, intr0)[0]
    m = ans["intrinsics"]
    np.testing.assert_allclose([m["fx"], m["fy"], m["cx"], m["cy"]], intr[:4], atol=1e-3)
    np.testing.assert_allclose(m["D"], intr[5:], atol=1e-5)
    assert ans["n_outliers"] == 0 and ans["noise_px"] == noise
    # measured: 8.5e-6 (at the distance) and 2.2e-6 (infinity) of relative difference, our central
    # differences against mrcal's analytic gradients; a different definition (depth for range, no
    # mean over the frames, one view's pose) is off by per cents
    assert np.all(np.isfinite(ours.sigma))
    np.testing.assert_allclose(ours.sigma, ans["sigma_at_distance"], rtol=1e-4)
    np.testing.assert_allclose(ours_inf.sigma, ans["sigma_at_infinity"], rtol=1e-4)
    # and the distance matters (the test would not pass with the infinity values)
    assert np.max(np.abs(ours.sigma / ours_inf.sigma - 1)) > 0.05


@pytest.mark.parametrize(("model", "dist"), [("plumb_bob", (-0.28, 0.09, 0.001, -0.0007, -0.012)),
                                             ("rational_polynomial", (0.4, -0.1, 0.001, -0.0007, 0.01, 0.7, -0.05,
                                                                      0.02))])
def test_a_cameramodel_projects_and_unprojects_as_our_camera(tmp_path: Path, model: str, dist: tuple) -> None:
    cam = Camera.from_params(610.0, 612.5, 331.2, 238.7, dist=list(dist), width=640, height=480, model=model)
    path = tmp_path / "cam.cameramodel"
    rng = np.random.default_rng(0)
    uv = np.c_[rng.uniform(0, 640, 200), rng.uniform(0, 480, 200)]
    rays = cam.unproject(uv)
    pts = rays * rng.uniform(0.3, 20.0, (200, 1))
    w = mrcal_bridge.model(write=path, K=cam.K, D=cam.D, distortion=model, image_size=(640, 480))
    assert w["lensmodel"] == mrcal_bridge.LENSMODEL_OF_ROS[model]
    r = mrcal_bridge.model(read=path, project=pts, unproject=uv)
    assert r["image_size"] == [640, 480] and r["distortion_model"] == model
    np.testing.assert_allclose(mrcal_bridge.K_of(r["intrinsics"]), cam.K, rtol=1e-15)
    np.testing.assert_allclose(r["projected"], uv, atol=1e-6)  # mrcal projects our rays onto our pixels
    np.testing.assert_allclose(r["projected"], cam.project(pts), atol=1e-9)
    np.testing.assert_allclose(r["unprojected"], rays, atol=1e-8)


def test_the_judge_refuses_what_is_not_a_chessboard_with_a_reason(session) -> None:
    _, obj, corners = session
    bent = obj.copy()
    bent[5, 0] += 0.003  # one corner off the regular grid
    with pytest.raises(mrcal_bridge.JudgeError, match="regular square grid"):
        mrcal_bridge.calibrate(corners, bent, (W, H), focal=800.0)
    with pytest.raises(mrcal_bridge.JudgeError, match="focal estimate"):
        mrcal_bridge.calibrate(corners, obj, (W, H))
