"""Stereo and rig workflows (workflows/stereo.py) and their commands: pairing, files, numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rig_sessions import rendered, rendered_three, rotation_error_deg

from pascal_calib_ros.cli import main
from pascal_calib_ros.io.calibration_json import read_calibration_json
from pascal_calib_ros.io.camera_yaml import read_camera_yaml
from pascal_calib_ros.io.stereo_yaml import read_rig_yaml, read_stereo_yaml
from pascal_calib_ros.sim.rig import write_rig
from pascal_calib_ros.workflows.stereo import PairingError, pair_files, parse_camera_args


def _files(folder: Path, names: list[str]) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for n in names:
        (folder / n).write_bytes(b"")
        out.append(folder / n)
    return out


def test_pairing_by_stem_then_number_then_order(tmp_path: Path) -> None:
    left = _files(tmp_path / "l", ["0001.png", "0002.png", "0003.png"])
    right = _files(tmp_path / "r", ["0002.png", "0003.png", "0004.png"])
    p = pair_files([left, right], ["left", "right"])
    assert p.how == "by file stem" and p.shots == ["0001", "0002", "0003", "0004"]
    assert p.paths[0][3] is None and p.paths[1][0] is None and len(p.unmatched) == 2
    # camera_calibration's archive: left-0001.png, right-0001.png
    left = _files(tmp_path / "a", ["left-0001.png", "left-0002.png"])
    right = _files(tmp_path / "b", ["right-0002.png", "right-0001.png"])
    p = pair_files([left, right], ["left", "right"])
    assert p.how == "by the number in the file names"
    assert [q.name for q in p.paths[1] if q is not None] == ["right-0001.png", "right-0002.png"]
    left = _files(tmp_path / "c", ["a.png", "b.png"])
    right = _files(tmp_path / "d", ["x.png", "y.png"])
    p = pair_files([left, right], ["left", "right"])
    assert p.how.startswith("by sorted order") and [q.name for q in p.paths[1] if q] == ["x.png", "y.png"]
    with pytest.raises(PairingError, match="different numbers of images"):
        pair_files([left, right[:1]], ["left", "right"])
    with pytest.raises(PairingError, match="no images for right"):
        pair_files([left, []], ["left", "right"])
    with pytest.raises(PairingError, match="NAME=GLOB"):
        parse_camera_args(["front", "b=x"])
    with pytest.raises(PairingError, match="twice"):
        parse_camera_args(["a=x", "a=y"])


def test_stereo_command_writes_the_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``pascal-calib stereo`` on a rendered head: left.yaml, right.yaml, stereo.yaml; the rig
    transform within 0.02 deg and 0.3 mm of the truth; each camera's report."""
    s = rendered("pair")
    write_rig(s, tmp_path / "in")
    out = tmp_path / "out"
    code = main(["stereo", "--target", "ring_grid_a4", "--left", str(tmp_path / "in" / "left"), "--right",
                 str(tmp_path / "in" / "right" / "*.png"), "-o", str(out), "--gamma", "2.2", "--camera-name", "head",
                 "--report", str(out / "report")])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "shots paired by file stem: 12 shots" in text and "static_transform_publisher" in text
    st = read_stereo_yaml(out / "stereo.yaml")
    Et = s.extrinsic(1)
    assert np.linalg.norm(rotation_error_deg(st["rig"].R, Et.R)) < 0.02
    assert 1000 * np.linalg.norm(st["rig"].translation - Et.translation) < 0.3
    assert 0 < st["epipolar_rms_px"] < 0.2
    left, right = read_camera_yaml(out / "left.yaml"), read_camera_yaml(out / "right.yaml")
    assert (left.camera_name, right.camera_name) == ("head/left", "head/right")
    assert right.P[0, 3] < 0 and left.P[0, 3] == 0
    assert (out / "report" / "left" / "report.pdf").is_file() and (out / "report" / "right" / "report.json").is_file()
    assert (out / "report" / "stereo.pdf").is_file() and (out / "report" / "stereo.png").is_file()
    # each camera's record (what verify and export read): its intrinsics' covariance from the joint fit
    for c, name in enumerate(("left", "right")):
        rec = read_calibration_json(out / f"{name}.calibration.json")
        assert rec.camera_name == f"head/{name}" and rec.covariance is not None
        truth = s.spec.cameras[c].camera
        for i, p in enumerate(("fx", "fy", "cx", "cy")):
            err = rec.camera.K.ravel()[(0, 4, 2, 5)[i]] - truth.K.ravel()[(0, 4, 2, 5)[i]]
            assert 0 < rec.std[p] < 1.0 and abs(err) < 4 * rec.std[p] + 0.05, (name, p, err, rec.std[p])
    # bad input: exit 2 and nothing written
    bad = main(["stereo", "--target", "ring_grid_a4", "--left", str(tmp_path / "none"), "--right",
                str(tmp_path / "in" / "right"), "-o", str(tmp_path / "out2")])
    assert bad == 2 and not (tmp_path / "out2").exists()


def test_rig_command_connects_cameras_transitively(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Three cameras in a row; the outer two never see a shot together: each camera's pose in
    the first's frame from the chain through the middle one, within its sigma."""
    s = rendered_three()
    assert not np.any(s.seen[0] & s.seen[2])
    write_rig(s, tmp_path / "in")
    out = tmp_path / "out"
    code = main(["rig", "--target", "ring_grid_a4", "--camera", f"a={tmp_path / 'in' / 'a'}", "--camera",
                 f"b={tmp_path / 'in' / 'b' / '*.png'}", "--camera", f"c={tmp_path / 'in' / 'c'}", "-o", str(out),
                 "--gamma", "2.2"])
    text = capsys.readouterr().out
    assert code == 0, text
    cams = read_rig_yaml(out / "rig.yaml")
    assert [c.name for c in cams] == ["a", "b", "c"] and all((out / c.yaml_file).is_file() for c in cams)
    assert all(read_calibration_json(out / f"{c.name}.calibration.json").covariance is not None for c in cams)
    for c in (1, 2):
        truth = s.spec.cameras[c].pose
        dt = 1000 * (cams[c].pose.translation - truth.translation)
        dr = rotation_error_deg(cams[c].pose.R, truth.R)
        assert np.all(np.abs(dt) < 4 * cams[c].sigma_translation_mm + 0.05), (c, dt, cams[c].sigma_translation_mm)
        assert np.all(np.abs(dr) < 4 * cams[c].sigma_rotation_deg + 0.002), (c, dr, cams[c].sigma_rotation_deg)
        assert np.linalg.norm(dt) < 1.0 and np.linalg.norm(dr) < 0.05
