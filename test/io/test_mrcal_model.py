"""mrcal ``.cameramodel`` export (``io/mrcal_model.py``): read back by mrcal itself (in its side venv,
Python 3.12/3.13: ``$PASCAL_MRCAL_PYTHON`` or ``.venv-mrcal``; skipped with the reason when absent)
and projected with ``mrcal.project`` within 1e-6 px of our projection over the whole image; our
reader reads every OPENCV* variant and refuses what it cannot hold."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from export_cases import FISHEYE, PLUMB, RATIONAL, grid_points

from pascal_calib_ros.analysis.refits.refit_splined import refit_splined
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.io.format_error import CalibrationFileError
from pascal_calib_ros.io.mrcal_model import (
    MrcalModel,
    camera_of_mrcal_model,
    mrcal_model_of_camera,
    mrcal_model_text,
    parse_mrcal_model,
    read_mrcal_model,
    write_mrcal_model,
)

ROOT = Path(__file__).resolve().parents[2]
PROJECT = """
import sys, numpy as np, mrcal
m = mrcal.cameramodel(sys.argv[1])
np.save(sys.argv[3], mrcal.project(np.load(sys.argv[2]), *m.intrinsics()))
print(m.intrinsics()[0], list(m.imagersize()))
"""



def mrcal_python() -> Path | None:
    env = os.environ.get("PASCAL_MRCAL_PYTHON")
    py = Path(env) if env else ROOT / ".venv-mrcal" / "bin" / "python"
    return py if py.exists() else None


def mrcal_project(model: Path, X: np.ndarray, tmp: Path) -> tuple[np.ndarray, str]:
    py = mrcal_python()
    if py is None:
        pytest.skip("mrcal is not installed here: no $PASCAL_MRCAL_PYTHON and no .venv-mrcal (mrcal has wheels for "
                    "Python 3.12/3.13 only; make one with tools/mrcal_venv)")
    np.save(tmp / "X.npy", X)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    r = subprocess.run([str(py), "-c", PROJECT, str(model), str(tmp / "X.npy"), str(tmp / "q.npy")],
                       capture_output=True, text=True, timeout=300, env=env)
    if r.returncode != 0 and "No module named 'mrcal'" in r.stderr:
        pytest.skip(f"{py} has no mrcal")
    assert r.returncode == 0, r.stderr
    return np.load(tmp / "q.npy"), r.stdout


@pytest.mark.parametrize("cam", [PLUMB, RATIONAL], ids=["plumb_bob", "rational_polynomial"])
def test_mrcal_reads_what_we_wrote_and_projects_as_we_do(tmp_path: Path, cam: Camera) -> None:
    path = write_mrcal_model(tmp_path / "cam.cameramodel", mrcal_model_of_camera(cam), note="from a test")
    X = grid_points(cam)
    q, out = mrcal_project(path, X, tmp_path)
    assert f"LENSMODEL_OPENCV{5 if cam.model == 'plumb_bob' else 8}" in out
    assert np.abs(q - cam.project(X)).max() < 1e-6


def test_mrcal_projects_our_splined_refit_of_a_fisheye_as_we_do(tmp_path: Path) -> None:
    """The splined stereographic model (mrcal's, for a fisheye) as mrcal projects it, over the whole
    image including rays beyond 90 degrees, within 1e-6 px of our implementation of it."""
    res = refit_splined(FISHEYE, force=True)
    spline = res.camera.spline  # type: ignore[attr-defined]
    path = write_mrcal_model(tmp_path / "f.cameramodel", MrcalModel(spline.lensmodel, spline.intrinsics, 640, 480))
    us, vs = np.meshgrid(np.arange(0.0, 641.0, 8.0), np.arange(0.0, 481.0, 8.0))
    rays = FISHEYE.unproject(np.stack([us.ravel(), vs.ravel()], 1))
    X = 3.0 * rays[np.all(np.isfinite(rays), 1)]
    assert (X[:, 2] < 0).any()  # beyond 90 degrees
    q, out = mrcal_project(path, X, tmp_path)
    assert "LENSMODEL_SPLINED_STEREOGRAPHIC" in out
    assert np.abs(q - spline.project(X)).max() < 1e-6
    assert res.rms_px < 0.01 and np.abs(spline.project(X) - FISHEYE.project(X)).max() < 0.2  # to the image's corners


@pytest.mark.parametrize("cam", [PLUMB, RATIONAL], ids=["plumb_bob", "rational_polynomial"])
def test_round_trip_is_exact(tmp_path: Path, cam: Camera) -> None:
    model = mrcal_model_of_camera(cam)
    assert model.lensmodel == ("LENSMODEL_OPENCV5" if cam.model == "plumb_bob" else "LENSMODEL_OPENCV8")
    back = camera_of_mrcal_model(read_mrcal_model(write_mrcal_model(tmp_path / "c.cameramodel", model)))
    assert back.model == cam.model and np.array_equal(back.K, cam.K) and np.array_equal(back.D, cam.D)


def test_other_opencv_variants_read_and_the_rest_refused() -> None:
    base = [500.0, 501.0, 320.0, 240.0]
    pin = camera_of_mrcal_model(MrcalModel("LENSMODEL_PINHOLE", np.array(base), 640, 480))
    assert pin.model == "plumb_bob" and not np.any(pin.D)
    four = camera_of_mrcal_model(MrcalModel("LENSMODEL_OPENCV4", np.array([*base, 0.1, -0.2, 0.01, 0.02]), 640, 480))
    assert list(four.D) == [0.1, -0.2, 0.01, 0.02, 0.0]
    twelve = camera_of_mrcal_model(MrcalModel("LENSMODEL_OPENCV12", np.array(base + [0.1] * 8 + [0.0] * 4), 640, 480))
    assert twelve.model == "rational_polynomial"
    with pytest.raises(CalibrationFileError, match="thin-prism"):
        camera_of_mrcal_model(MrcalModel("LENSMODEL_OPENCV12", np.array(base + [0.1] * 12), 640, 480))
    with pytest.raises(CalibrationFileError, match="no equivalent"):
        camera_of_mrcal_model(MrcalModel("LENSMODEL_CAHVOR", np.array(base + [0.0] * 5), 640, 480))
    with pytest.raises(CalibrationFileError, match="no equidistant model"):
        mrcal_model_of_camera(FISHEYE)


def test_the_reader_evaluates_no_code_and_reads_mrcals_own_layout() -> None:
    with pytest.raises(CalibrationFileError, match="not an mrcal"):
        parse_mrcal_model("{'lensmodel': __import__('os').system('true'), 'intrinsics': [], 'imagersize': [1, 1]}")
    text = mrcal_model_text(mrcal_model_of_camera(PLUMB), note="two\nlines")
    assert text.startswith("# two\n# lines\n{")
    # mrcal's own writer keeps 10 digits and writes the optimisation inputs as a bytes literal
    own = ("# generated by mrcal\n{\n    'lensmodel':  'LENSMODEL_OPENCV8',\n    # intrinsics are fx,fy,cx,cy,...\n"
           "    'intrinsics': [ 1000.123457, 1001, 640.5, 360.25, 0.1, -0.2, 0, 0, 0, 0.3, 0, 0,],\n"
           "    'rt_cam_ref': [ 0, 0, 0, 0.1, 0, 0,],\n    'extrinsics': [ 0, 0, 0, 0.1, 0, 0,], # for compat\n"
           "    'imagersize': [ 1280, 720,],\n    'optimization_inputs': b'\\x00\\x01',\n}\n")
    m = parse_mrcal_model(own)
    assert m.width == 1280 and m.rt_cam_ref[3] == 0.1
    assert camera_of_mrcal_model(m).model == "rational_polynomial"
