"""Refit into another lens model (``analysis/refits/refit.py``) and ``pascal-calib export``: the error a refit
states matches a direct measurement within 5 % (the exported file read back by OpenCV, the best
rotation found by a derivative-free search, a grid of another step); a refit too far off is refused
with where it fails, unless forced; every format and the hand-eye exports through the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from export_cases import FISHEYE, PLUMB, RATIONAL, grid_points
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from pascal_calib_ros.analysis.refits.refit import RefitError, refit_camera
from pascal_calib_ros.analysis.statistics.compare import Region
from pascal_calib_ros.cli import main
from pascal_calib_ros.errors import PascalCalibError
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.io.calibration_files import read_calibration_file
from pascal_calib_ros.io.calibration_json import CalibrationRecord, write_calibration_json
from pascal_calib_ros.io.kalibr_camchain import read_kalibr_camchain
from pascal_calib_ros.io.mrcal_model import parse_mrcal_model
from pascal_calib_ros.io.mrcal_splined import SplinedModel, parse_lensmodel
from pascal_calib_ros.workflows.verify import reference_of_file

# a lens whose rational radial factor plumb_bob holds to a few hundredths of a pixel only
WIDE = Camera.from_params(550.0, 551.0, 400.3, 300.1, dist=[0.4, -0.1, 0.0005, -0.0003, 0.0, 0.65, -0.05, 0.0],
                          width=800, height=600, model="rational_polynomial")
HULLS = [np.array([[150.0, 100.0], [650.0, 110.0], [640.0, 500.0], [160.0, 490.0]]),
         np.array([[60.0, 60.0], [300.0, 80.0], [200.0, 300.0]])]


def direct_error(source: Camera, path: Path, step: float, mask: np.ndarray | None = None) -> tuple[float, float]:
    """RMS and worst px between the source and the exported file as OpenCV reads it, after the best
    rotation (Nelder-Mead over the rotation vector from zero), over cell centres of ``step`` px."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    K, D = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    fs.release()
    us, vs = np.meshgrid(np.arange(step / 2, source.width, step), np.arange(step / 2, source.height, step))
    q = np.stack([us.ravel(), vs.ravel()], 1)
    if mask is not None:
        q = q[mask[q[:, 1].astype(int), q[:, 0].astype(int)]]
    rays = source.unproject(q)

    def residual(rv: np.ndarray) -> np.ndarray:
        p = Rotation.from_rotvec(rv).apply(rays)
        return cv2.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)[0].reshape(-1, 2) - q

    sol = minimize(lambda rv: float(np.sum(residual(rv) ** 2)), np.zeros(3), method="Nelder-Mead",
                   options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 4000})
    rms = float(np.sqrt(np.mean(np.sum(residual(sol.x) ** 2, 1))))
    # the worst: the grid and every pixel centre within 3 px of the region's rim (the rotation found on the grid)
    m = np.ones((source.height, source.width), np.uint8) if mask is None else mask.astype(np.uint8)
    band = (m > 0) & ~(cv2.erode(np.pad(m, 1), np.ones((7, 7), np.uint8))[1:-1, 1:-1] > 0)
    vv, uu = np.nonzero(band)
    qa = np.concatenate([q, np.stack([uu, vv], 1) + 0.5])
    p = Rotation.from_rotvec(sol.x).apply(source.unproject(qa))
    qb = cv2.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)[0].reshape(-1, 2)
    return rms, float(np.linalg.norm(qb - qa, axis=1).max())


def write_source(tmp_path: Path, cam: Camera, hulls: list[np.ndarray] | None = None) -> Path:
    return write_calibration_json(tmp_path / "src.calibration.json", CalibrationRecord(cam, view_hulls=hulls or []))


@pytest.mark.parametrize("region", ["image", "observed field"])
def test_the_stated_error_matches_a_direct_measurement(tmp_path: Path, region: str, capsys: pytest.CaptureFixture
                                                       ) -> None:
    src = write_source(tmp_path, WIDE, HULLS)
    args = ["export", str(src), "--to", "opencv", "--model", "plumb_bob", "-o", str(tmp_path / "pb.yaml"), "--force"]
    mask = None
    if region != "image":
        args += ["--region", str(src)]
        mask = Region(HULLS, 800, 600).mask
    assert main(args) == 0
    out = capsys.readouterr().out
    stated_rms = float(out.split("projection error ")[1].split(" px rms")[0])
    stated_worst = float(out.split("px rms, ")[1].split(" px worst")[0])
    rms, worst = direct_error(WIDE, tmp_path / "pb.yaml", 3.0, mask)
    assert stated_rms > 0.002  # a real refit error, not a trivial one
    assert abs(stated_rms / rms - 1) < 0.05, (stated_rms, rms)
    assert abs(stated_worst / worst - 1) < 0.05, (stated_worst, worst)


def test_a_refit_too_far_off_is_refused_with_where_it_fails(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(RefitError, match="Refused") as e:
        refit_camera(WIDE, "none")
    assert "within 0.25 px inside" in str(e.value) and "top-left" in str(e.value)
    src = write_source(tmp_path, RATIONAL)
    assert main(["export", str(src), "--to", "opencv", "--model", "none", "-o", str(tmp_path / "p.yaml")]) == 1
    assert not (tmp_path / "p.yaml").exists() and "nothing written" in capsys.readouterr().err
    ok = refit_camera(WIDE, "plumb_bob", Region(HULLS, 800, 600).mask, "field")
    assert ok.ok and ok.worst_px < 0.25 and ok.where_it_fails() == ""
    with pytest.raises(RefitError, match="degrees"):  # a fisheye's rim is beyond any x/z model
        refit_camera(FISHEYE, "plumb_bob")


def test_kalibr_refits_k3_away_and_keeps_an_exact_model(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    src = write_source(tmp_path, PLUMB, HULLS)
    out = tmp_path / "chain.yaml"
    assert main(["export", str(src), "--to", "kalibr", "--region", str(src), "-o", str(out), "--rostopic", "/c"]) == 0
    assert "plumb_bob -> plumb_bob_k3_fixed" in capsys.readouterr().out
    cam = read_kalibr_camchain(out)[0].camera
    assert cam.D[4] == 0.0 and cam.model == "plumb_bob"
    fish = write_source(tmp_path, FISHEYE)
    assert main(["export", str(fish), "--to", "kalibr", "-o", str(out)]) == 0
    back = read_kalibr_camchain(out)[0].camera  # equidistant: written as it is, no refit
    assert back.model == "equidistant" and np.array_equal(back.D, FISHEYE.D)


def test_every_format_through_the_cli_and_diff_reads_them(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    src = write_source(tmp_path, RATIONAL)
    for to in ("opencv", "mrcal", "json"):
        out = tmp_path / f"c.{to}"
        assert main(["export", str(src), "--to", to, "-o", str(out)]) == 0
        assert main(["diff", str(src), str(out)]) == 0
        assert "rms 0.000 px, max 0.000 px" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "missing.yaml"), "--to", "opencv", "-o", str(tmp_path / "x")]) == 2
    assert main(["export", str(src), "--to", "opencv", "--max-error", "-1", "-o", str(tmp_path / "x")]) == 2
    assert main(["export", str(src), "--to", "urdf", "-o", str(tmp_path / "x")]) == 2  # not a hand-eye file


def test_a_fisheye_is_refitted_for_mrcal_with_its_error_stated(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    # mrcal has no equidistant model: its splined stereographic one, over the whole image (rays beyond 90 degrees)
    src = write_source(tmp_path, FISHEYE)
    out = tmp_path / "f.cameramodel"
    assert main(["export", str(src), "--to", "mrcal", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "equidistant -> LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=24" in text
    stated_rms = float(text.split("projection error ")[1].split(" px rms")[0])
    assert stated_rms < 0.01
    model = parse_mrcal_model(out.read_text())
    spline = SplinedModel(*parse_lensmodel(model.lensmodel)[1:], model.intrinsics, model.width, model.height)
    X = 2.0 * FISHEYE.unproject(np.array([[5.0, 5.0], [320.0, 240.0], [600.0, 20.0], [100.0, 400.0]]))
    assert np.abs(spline.project(X) - FISHEYE.project(X)).max() < 0.2
    # the splined file reads back (diff compares it; verify refuses it; export refits it only when asked)
    assert main(["diff", str(src), str(out), "--step", "8"]) == 0
    measured = float(capsys.readouterr().out.split("rms ")[1].split(" px")[0])
    assert measured < 0.01
    with pytest.raises(PascalCalibError, match="compare it with pascal-calib diff"):
        reference_of_file(read_calibration_file(out))
    assert main(["export", str(out), "--to", "opencv", "-o", str(tmp_path / "o.yaml")]) == 2


def test_hand_eye_files_export_to_urdf_and_static_transform(tmp_path: Path) -> None:
    he = tmp_path / "hand_eye.yaml"
    he.write_text(json.dumps({"mode": "eye_to_hand", "parent_frame": "base_link", "child_frame": "cam",
                              "translation": [1.0, 0.2, 0.5], "rotation": [0.0, 0.0, 0.0, 1.0],
                              "translation_std_mm": [0.1, 0.1, 0.1], "rotation_std_deg": [0.01, 0.01, 0.01]}))
    assert main(["export", str(he), "--to", "urdf", "-o", str(tmp_path / "j.urdf")]) == 0
    assert '<parent link="base_link"/>' in (tmp_path / "j.urdf").read_text()
    assert main(["export", str(he), "--to", "static_transform", "-o", str(tmp_path / "s.sh")]) == 0
    assert "--frame-id base_link --child-frame-id cam" in (tmp_path / "s.sh").read_text()
    assert main(["export", str(he), "--to", "urdf", "--model", "none", "-o", str(tmp_path / "j.urdf")]) == 2


def test_points_of_the_grid_helper_cover_the_image() -> None:
    X = grid_points(PLUMB)
    q = PLUMB.project(X)
    assert q[:, 0].min() < 1 and q[:, 0].max() > 799 and q[:, 1].max() > 599
