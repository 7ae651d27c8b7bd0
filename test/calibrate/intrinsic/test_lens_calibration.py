"""Every lens model through the calibration pipeline and the CLI (issue 13)."""

import numpy as np
import pytest
import yaml
from cli_harness import run
from conftest import FISHEYE_SPEC, _session

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.calibrate.intrinsic.result import CalibrationError
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import calibration_errors
from pascal_calib_ros.geometry.image_field import observed_field_mask
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import resolve_target


def test_fisheye_grid_beyond_90_degrees(fisheye_grid_session: tuple) -> None:
    cam, _, dets = fisheye_grid_session
    angles = [np.degrees(np.arccos(cam.unproject(e.points)[:, 2])).max() for d in dets if d.ok for e in d.edges]
    assert max(angles) > 90  # the session really has rings behind the image plane
    res = calibrate(dets, resolve_target("ring_grid_a4"), CalibrationOptions(distortion="equidistant"))
    assert res.model == "equidistant" and len(res.D) == 4
    assert res.n_used == len(dets)  # every view used, the rim's too
    err = calibration_errors(cam, res.K, res.D, res.model)
    assert abs(err["fx_err_pct"]) < 0.1 and abs(err["fy_err_pct"]) < 0.1
    assert err["pp_err_px"] < 0.5 and err["model_err_px"] < 0.3


def test_plumb_bob_on_a_fisheye_is_refused_and_names_the_model(fisheye_grid_session: tuple) -> None:
    _, _, dets = fisheye_grid_session
    for model in ("plumb_bob", "rational_polynomial"):
        with pytest.raises(CalibrationError, match="--distortion equidistant"):
            calibrate(dets, resolve_target("ring_grid_a4"), CalibrationOptions(distortion=model))


def test_rational_wide_angle_grid() -> None:
    spec = SessionSpec(width=640, height=480, focal=320, lens="rational_polynomial",
                       dist=(0.6, -0.05, 0.0005, -0.0003, 0.0, 0.95, 0.1, 0.0), views=8, pixel_range=(0.15, 0.85),
                       size_range=(0.35, 0.55), seed=4)
    cam, _, dets = _session(resolve_target("ring_grid_a4"), spec)
    res = calibrate(dets, resolve_target("ring_grid_a4"), CalibrationOptions(distortion="rational_polynomial"))
    assert res.model == "rational_polynomial" and len(res.D) == 8
    field = observed_field_mask(res.edge_points, ImageSize(640, 480))
    err = calibration_errors(cam, res.K, res.D, res.model, mask=field)
    assert abs(err["fx_err_pct"]) < 0.1 and err["pp_err_px"] < 1.0 and err["model_err_px"] < 0.3


def test_too_few_views_for_the_rational_model_say_so(fisheye_grid_session: tuple) -> None:
    _, _, dets = fisheye_grid_session
    with pytest.raises(CalibrationError, match="rational_polynomial model's 8 distortion coefficients"):
        calibrate(dets[:4], resolve_target("ring_grid_a4"), CalibrationOptions(distortion="rational_polynomial"))


def test_cli_fisheye_session_writes_an_equidistant_yaml(tmp_path) -> None:
    s = FISHEYE_SPEC
    r = run("render", "--target", "ring_grid_a4", "--out", str(tmp_path / "s"), "--size", f"{s.width}x{s.height}",
            "--views", "5", "--focal", str(s.focal), "--lens", "equidistant", "--dist", ",".join(map(str, s.dist)),
            "--min-size", "0.3", "--max-size", "0.5", "--seed", "3")
    assert r.returncode == 0, r.stderr
    out = tmp_path / "fish.yaml"
    r = run("calibrate", "--target", "ring_grid_a4", "--distortion", "equidistant", "-o", str(out),
            "--report", str(tmp_path / "rep"), str(tmp_path / "s"))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "D equidistant (k1 k2 k3 k4)" in r.stdout
    doc = yaml.safe_load(out.read_text())
    assert doc["distortion_model"] == "equidistant" and len(doc["distortion_coefficients"]["data"]) == 4
    K = np.array(doc["camera_matrix"]["data"]).reshape(3, 3)
    P = np.array(doc["projection_matrix"]["data"]).reshape(3, 4)
    assert abs(K[0, 0] / s.focal - 1) < 0.005
    half = min(K[0, 2], s.width - 1 - K[0, 2])  # rectified pinhole view: +-60 degrees horizontally
    assert abs(np.degrees(np.arctan(half / P[0, 0])) - 60) < 1e-6 and P[0, 2] == K[0, 2]
    assert (tmp_path / "rep" / "report.png").exists()


def test_single_ring_through_a_fisheye() -> None:
    """A large ring is no conic under a fisheye: detection for a wide lens tolerates that, the
    start draws the edges in a virtual pinhole camera, the refinement uses the model itself."""
    from pascal_calib_ros.detect.detection import DetectionParams
    from pascal_calib_ros.detect.target_detector import detect_target
    from pascal_calib_ros.sim.session import render_session_views

    target = resolve_target("ring_a4")
    spec = SessionSpec(width=640, height=480, focal=190, lens="equidistant", dist=FISHEYE_SPEC.dist, views=8,
                       pixel_range=(0.05, 0.95), size_range=(0.15, 0.3), seed=3)
    cam, views = render_session_views(target, spec)
    narrow = [detect_target(v.image, target) for v in views]
    dets = [detect_target(v.image, target, DetectionParams.for_lens(True)) for v in views]
    assert sum(d.ok for d in dets) >= sum(d.ok for d in narrow) and sum(d.ok for d in dets) >= 7
    res = calibrate(dets, target, CalibrationOptions(distortion="equidistant"))
    err = calibration_errors(cam, res.K, res.D, res.model)
    assert res.n_used == sum(d.ok for d in dets)
    assert abs(err["fx_err_pct"]) < 0.1 and err["pp_err_px"] < 0.5
