"""Projection difference between two calibrations (``analysis/statistics/compare.py``, ``pascal-calib diff``).

Every number the module reports is checked against a direct computation done here by another
route: the same grid built independently, the best rotation found by a derivative-free
Nelder-Mead search over the rotation vector (started at zero, not at the Kabsch alignment the
module starts from), and the RMS / max of what remains.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from pascal_calib_ros.analysis.statistics.compare import (
    CompareError,
    projection_difference,
    region_from_report,
)
from pascal_calib_ros.errors import PascalCalibError
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.io import CalibrationRecord, camera_info_of, read_calibration_file, write_camera_yaml

F = 550.0
PLUMB = Camera.from_params(F, F, 400.0, 300.0, dist=[-0.2, 0.05, 0.0, 0.0, 0.0], width=800, height=600)
RATIONAL_D = [0.4, -0.1, 0.0005, -0.0003, 0.0, 0.65, -0.05, 0.0]
RATIONAL = Camera.from_params(F, F, 400.0, 300.0, dist=RATIONAL_D, width=800, height=600,
                              model="rational_polynomial")
FISHEYE_D = [0.02, -0.005, 0.001, -0.0002]
FISHEYE = Camera.from_params(190.0, 190.0, 320.0, 240.0, dist=FISHEYE_D, width=640, height=480, model="equidistant")
HULLS = [[[200, 150], [600, 150], [600, 450], [200, 450]], [[100, 100], [300, 100], [200, 300]]]


def changed(cam: Camera, focal_scale: float = 1.0, dcx: float = 0.0, dcy: float = 0.0) -> Camera:
    K = cam.K.copy()
    K[0, 0] *= focal_scale
    K[1, 1] *= focal_scale
    K[0, 2] += dcx
    K[1, 2] += dcy
    return Camera(K, cam.D.copy(), cam.width, cam.height, cam.model)


def direct(a: Camera, b: Camera, mask: np.ndarray | None = None, step: float = 16.0) -> dict[str, float]:
    """RMS and max pixel difference after the best rotation, and its angle: Nelder-Mead on the
    sum of squared pixel differences over the rotation vector, from zero."""
    us = np.arange(step / 2, a.width, step)
    vs = np.arange(step / 2, a.height, step)
    q = np.array([(u, v) for v in vs for u in us])
    if mask is not None:
        q = q[[bool(mask[int(v), int(u)]) for u, v in q]]
    rays = a.unproject(q)
    assert np.all(np.isfinite(rays))

    def residual(w: np.ndarray) -> np.ndarray:
        return np.asarray(b.project(Rotation.from_rotvec(w).apply(rays)) - q)

    best = minimize(lambda w: float(np.sum(residual(w) ** 2)), np.zeros(3), method="Nelder-Mead",
                    options={"xatol": 1e-11, "fatol": 1e-12, "maxiter": 20000, "maxfev": 20000,
                             "initial_simplex": np.vstack([np.zeros(3), 0.01 * np.eye(3)])})
    d = np.linalg.norm(residual(best.x), axis=1)
    return {"rms": float(np.sqrt(np.mean(d ** 2))), "max": float(d.max()), "n": len(q),
            "deg": float(np.degrees(np.linalg.norm(best.x)))}


@pytest.mark.parametrize("cam", [PLUMB, RATIONAL, FISHEYE], ids=["plumb_bob", "rational", "equidistant"])
def test_a_model_against_itself_differs_by_nothing(cam: Camera) -> None:
    for distance in (None, 2.0):
        d = projection_difference(cam, cam, distance=distance)
        assert d.n == len(np.arange(8, cam.width, 16)) * len(np.arange(8, cam.height, 16)) and d.n_excluded == 0
        assert d.rms < 1e-6 and d.max < 1e-6
        assert d.rotation_deg < 1e-6 and np.abs(d.transform.translation).max() < 1e-9


def test_focal_scale_cannot_be_absorbed_by_a_rotation() -> None:
    b = changed(PLUMB, focal_scale=1.001)
    d = projection_difference(PLUMB, b)
    ref = direct(PLUMB, b)
    assert d.n == ref["n"] == 1850
    assert d.rms == pytest.approx(ref["rms"], rel=0.05) and d.max == pytest.approx(ref["max"], rel=0.05)
    # nearly all of it remains: the raw difference (no rotation) is about the same
    raw = np.linalg.norm(b.project(PLUMB.unproject(d.pixels)) - d.pixels, axis=1)
    assert d.rms > 0.95 * np.sqrt(np.mean(raw ** 2)) and d.rms > 0.2
    assert d.rotation_deg < 0.002
    assert d.summary() == (f"projection difference: rms {d.rms:.3f} px, max {d.max:.3f} px over 1850 points "
                           f"(fitted rotation {d.rotation_deg:.4f} deg)")


def test_principal_point_shift_is_mostly_a_rotation() -> None:
    b = changed(PLUMB, dcx=3.0)
    d = projection_difference(PLUMB, b)
    ref = direct(PLUMB, b)
    assert d.rms == pytest.approx(ref["rms"], rel=0.05) and d.max == pytest.approx(ref["max"], rel=0.05)
    assert d.rms < 0.15 * 3.0  # a rotation takes most of the 3 px away
    assert d.rotation_deg == pytest.approx(ref["deg"], rel=0.01)
    assert d.rotation_deg == pytest.approx(np.degrees(np.arctan(3.0 / F)), rel=0.1)
    axis = d.rotvec / np.linalg.norm(d.rotvec)
    assert abs(axis[1]) > 0.999  # about the camera's y axis (a pan), as a shift of cx asks


def test_rational_polynomial_model() -> None:
    assert np.all(np.isfinite(RATIONAL.unproject(np.array([[0.0, 0.0], [799.0, 599.0]]))))
    b = changed(RATIONAL, focal_scale=1.002, dcx=-2.0, dcy=1.0)
    d = projection_difference(RATIONAL, b)
    ref = direct(RATIONAL, b)
    assert d.n == ref["n"] and d.n_excluded == 0
    assert d.rms == pytest.approx(ref["rms"], rel=0.05) and d.max == pytest.approx(ref["max"], rel=0.05)
    assert d.rotation_deg == pytest.approx(ref["deg"], rel=0.02)


def test_fisheye_beyond_90_degrees() -> None:
    rays = FISHEYE.unproject(np.array([[0.0, 0.0]]))
    assert rays[0, 2] < 0  # the image corners see behind the camera plane
    b = changed(FISHEYE, dcx=2.0, dcy=-1.0)
    d = projection_difference(FISHEYE, b)
    ref = direct(FISHEYE, b)
    assert d.n == ref["n"] == 1200 and d.n_excluded == 0
    assert np.sum(FISHEYE.unproject(d.pixels)[:, 2] < 0) > 50
    assert d.rms == pytest.approx(ref["rms"], rel=0.05) and d.max == pytest.approx(ref["max"], rel=0.05)
    assert d.rotation_deg == pytest.approx(ref["deg"], rel=0.02)


def test_points_beyond_a_models_range_are_left_out_and_counted() -> None:
    """k1 = -0.45 folds the polynomial at about 316 px from the centre: the corners have no ray."""
    a = Camera.from_params(F, F, 400.0, 300.0, dist=[-0.45, 0.0, 0.0, 0.0, 0.0], width=800, height=600)
    d = projection_difference(a, changed(a, dcx=1.0))
    assert d.n_excluded > 100 and d.n + d.n_excluded == 1850
    assert np.all(np.isfinite(a.unproject(d.pixels)))
    assert np.all(np.hypot(d.pixels[:, 0] - 400.0, d.pixels[:, 1] - 300.0) < 330.0)
    assert d.max < 2.0  # no point from the far side of the fold


def test_finite_range_fits_a_translation_too() -> None:
    """At 1 m a 0.1 % focal change is mostly a camera moved back by about 1 mm (mrcal's range
    dependence); at infinity it is not absorbed at all."""
    b = changed(PLUMB, focal_scale=1.001)
    far, near = projection_difference(PLUMB, b), projection_difference(PLUMB, b, distance=1.0)
    assert near.rms < 0.1 * far.rms
    assert near.transform.translation[2] == pytest.approx(0.001, rel=0.2)
    assert np.all(far.transform.translation == 0)


def write_report_json(path: Path, width: int = 800, height: int = 600) -> Path:
    path.write_text(json.dumps({"image": {"width": width, "height": height},
                                "coverage": {"observed_fraction": 0.3, "view_hulls": HULLS}}))
    return path


def test_region_from_a_report_restricts_the_points(tmp_path: Path) -> None:
    region = region_from_report(write_report_json(tmp_path / "report.json"))
    assert (region.width, region.height) == (800, 600) and len(region.hulls) == 2
    b = changed(PLUMB, focal_scale=1.001)
    full = projection_difference(PLUMB, b)
    inside = projection_difference(PLUMB, b, region.mask)
    ref = direct(PLUMB, b, region.mask)
    assert inside.n == ref["n"] and 300 < inside.n < 0.5 * full.n
    polys = [np.asarray(h, np.float32) for h in HULLS]
    assert all(max(cv2.pointPolygonTest(p, (float(u), float(v)), True) for p in polys) >= -1.0
               for u, v in inside.pixels)
    # the worst of a focal change is in the corners, outside the region
    assert inside.max == pytest.approx(ref["max"], rel=0.05) and inside.max < 0.8 * full.max
    assert inside.rms == pytest.approx(ref["rms"], rel=0.05)


def test_refusals(tmp_path: Path) -> None:
    small = Camera.from_params(F, F, 320.0, 240.0, width=640, height=480)
    with pytest.raises(CompareError, match="different image sizes: 800x600 and 640x480"):
        projection_difference(PLUMB, small)
    with pytest.raises(CompareError, match="region is 640x480"):
        projection_difference(PLUMB, PLUMB, region_from_report(write_report_json(tmp_path / "r.json", 640, 480)).mask)
    with pytest.raises(CompareError, match="distance"):
        projection_difference(PLUMB, PLUMB, distance=0.0)
    (tmp_path / "bad.json").write_text(json.dumps({"image": {"width": 800, "height": 600}}))
    with pytest.raises(CompareError, match="view_hulls"):
        region_from_report(tmp_path / "bad.json")
    (tmp_path / "empty.json").write_text(json.dumps({"image": {"width": 8, "height": 6},
                                                      "coverage": {"view_hulls": []}}))
    with pytest.raises(CompareError, match="no view hulls"):
        region_from_report(tmp_path / "empty.json")
    with pytest.raises(CompareError, match=r"missing\.json"):
        region_from_report(tmp_path / "missing.json")
    assert issubclass(CompareError, PascalCalibError)


def run(*args: str) -> subprocess.CompletedProcess:
    exe = shutil.which("pascal-calib", path=str(Path(sys.executable).parent)) or "pascal-calib"
    return subprocess.run([exe, *args], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})


def write_yaml(path: Path, cam: Camera) -> Path:
    return write_camera_yaml(path, camera_info_of(CalibrationRecord(cam, "cam")))


def test_cli_diff(tmp_path: Path) -> None:
    a, b = write_yaml(tmp_path / "a.yaml", PLUMB), write_yaml(tmp_path / "b.yaml", changed(PLUMB, dcx=3.0))
    assert read_calibration_file(b).camera.K[0, 2] == 403.0
    expected = projection_difference(PLUMB, changed(PLUMB, dcx=3.0))
    report = write_report_json(tmp_path / "report.json")
    png = tmp_path / "plots" / "diff.png"
    r = run("diff", str(a), str(b), "--region", str(report), "--plot", str(png))
    assert r.returncode == 0, r.stderr
    line = r.stdout.splitlines()[0]
    assert re.fullmatch(r"projection difference: rms \d+\.\d{3} px, max \d+\.\d{3} px over \d+ points "
                        r"\(fitted rotation \d+\.\d{4} deg\)", line)
    inside = projection_difference(PLUMB, changed(PLUMB, dcx=3.0), region_from_report(report).mask)
    assert line == inside.summary() and inside.n < expected.n
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000
    r = run("diff", str(a), str(b))
    assert r.returncode == 0 and r.stdout.strip() == expected.summary()


def test_cli_diff_bad_input(tmp_path: Path) -> None:
    a = write_yaml(tmp_path / "a.yaml", PLUMB)
    small = write_yaml(tmp_path / "small.yaml", Camera.from_params(F, F, 320.0, 240.0, width=640, height=480))
    r = run("diff", str(a), str(small))
    assert r.returncode == 2 and "different image sizes: 800x600 and 640x480" in r.stderr and not r.stdout
    r = run("diff", str(a), str(tmp_path / "missing.yaml"))
    assert r.returncode == 2 and "missing.yaml" in r.stderr
