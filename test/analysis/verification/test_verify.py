"""``pascal-calib verify`` (``analysis/verification/``, ``workflows/verify.py``):
on renders of the unchanged camera the calibration holds; after f x 1.002, the principal point moved
by 1.5 px, or the camera turned by 0.1 deg on its mount it has changed, with what moved named.

One rendered arm session (eye in hand, ring grid, 640x480) is the calibration under test (intrinsics
and hand-eye); one fresh session of 8 poses is rendered four times from the same poses (unchanged,
each change). The study ``pascal-calib study verify`` measures the rates over 20 sessions."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from pascal_calib_ros.analysis.statistics.assessment import assess
from pascal_calib_ros.analysis.verification.fixed_views import VerifyError
from pascal_calib_ros.analysis.verification.hand_eye import HandEyeReference
from pascal_calib_ros.analysis.verification.verdict import CHANGED, HOLDS, verify_calibration
from pascal_calib_ros.calibrate.handeye import calibrate_hand_eye
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.cli import main
from pascal_calib_ros.detect.detection import DetectionParams
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.calibration_json import CalibrationRecord, sidecar_path, write_calibration_json
from pascal_calib_ros.io.camera_yaml import CameraInfoData, write_camera_yaml
from pascal_calib_ros.io.hand_eye_yaml import write_hand_eye_yaml, write_poses_yaml
from pascal_calib_ros.sim.arm import DEFAULT_HAND_EYE, ArmSpec, arm_poses, render_arm_images
from pascal_calib_ros.targets import resolve_target
from pascal_calib_ros.workflows.calibration_record import intrinsic_covariance, record_of_calibration
from pascal_calib_ros.workflows.hand_eye import HandEyeFrames, HandEyeOutcome

TARGET = resolve_target("ring_grid_a4")
PARAMS = DetectionParams(gamma=2.2)  # the renders' display gamma
BASE = ArmSpec(width=640, height=480, k1=-0.2, field_seed=5)
X_TRUE = DEFAULT_HAND_EYE["eye_in_hand"]
TURN = Transform.from_rotvec(np.radians(0.1) * np.array([0.6, -0.8, 0.0]))


def changed(cam: Camera, focal: float = 1.0, dcx: float = 0.0) -> Camera:
    K = cam.K.copy()
    K[0, 0] *= focal
    K[1, 1] *= focal
    K[0, 2] += dcx
    return Camera(K, cam.D.copy(), cam.width, cam.height, cam.model)


@pytest.fixture(scope="module")
def stored() -> dict:
    """The calibration under test: an arm session of 12 poses."""
    spec = replace(BASE, views=12, seed=11)
    session = arm_poses(spec, TARGET)
    imgs = render_arm_images(session, TARGET)
    dets = [detect_target(im, TARGET, PARAMS, name=n) for im, n in zip(imgs, session.names, strict=True)]
    res = calibrate_hand_eye(dets, list(session.robot_poses), TARGET, "eye_in_hand", CalibrationOptions())
    names, cov = intrinsic_covariance(res.calibration)
    ref = CalibrationRecord(res.calibration.camera(), distortion_choice=res.calibration.distortion_model,
                            parameters=names, covariance=cov)
    he = HandEyeReference("eye_in_hand", res.hand_eye, res.translation_std_mm, res.rotation_std_deg,
                          intrinsics_share_mm=res.intrinsics_share_mm, intrinsics_share_deg=res.intrinsics_share_deg)
    return {"result": res, "ref": ref, "he": he, "truth": session.camera}


def fresh(truth: Camera, hand_eye: Transform = X_TRUE) -> tuple[list, list, list[np.ndarray], list[str]]:
    """A fresh session of 8 poses with the camera ``truth`` on the mount ``hand_eye``."""
    session = arm_poses(replace(BASE, views=8, seed=23), TARGET, hand_eye=hand_eye)
    session.camera = truth
    imgs = render_arm_images(session, TARGET)
    dets = [detect_target(im, TARGET, PARAMS, name=n) for im, n in zip(imgs, session.names, strict=True)]
    return dets, list(session.robot_poses), imgs, session.names


@pytest.fixture(scope="module")
def unchanged(stored: dict) -> tuple:
    return fresh(stored["truth"])


def test_an_unchanged_camera_holds(stored: dict, unchanged: tuple) -> None:
    dets, robot, _, _ = unchanged
    v = verify_calibration(dets, TARGET, stored["ref"], robot, stored["he"])
    assert v.verdict == HOLDS, v.text()
    assert v.moved == [] and len(v.fresh.used) == 8
    assert all(g.p_value > v.alpha / 4 for g in v.intrinsics.groups) and v.hand_eye is not None
    assert v.hand_eye.p_value > v.alpha / 4 and v.hand_eye.rotation_deg < 0.05
    assert v.intrinsics.shift is not None and v.intrinsics.shift.rms < 3 * v.intrinsics.expected_shift_rms_px
    doc = json.loads(json.dumps(v.as_json(), allow_nan=False))
    assert doc["verdict"] == "holds" and {p["name"] for p in doc["parameters"]} >= {"fx", "fy", "cx", "cy", "k1"}
    assert doc["hand_eye"]["rotation_deg"] < 0.05 and doc["projection_shift_px"]["rms"] is not None


@pytest.mark.parametrize(("change", "named"), [({"focal": 1.002}, {"fx", "fy"}), ({"dcx": 1.5}, {"cx"})],
                         ids=["focal x 1.002", "principal point + 1.5 px"])
def test_a_changed_camera_is_found_and_what_moved_named(stored: dict, change: dict, named: set) -> None:
    dets, _, _, _ = fresh(changed(stored["truth"], **change))
    v = verify_calibration(dets, TARGET, stored["ref"])
    assert v.verdict == CHANGED, v.text()
    assert named <= set(v.moved), v.moved
    group = "focal length" if "fx" in named else "principal point"
    assert group in [g.name for g in v.intrinsics.groups if g.changed]


def test_a_camera_turned_on_its_mount_is_found(stored: dict) -> None:
    dets, robot, _, _ = fresh(stored["truth"], X_TRUE @ TURN)
    v = verify_calibration(dets, TARGET, stored["ref"], robot, stored["he"])
    assert v.verdict == CHANGED and v.hand_eye is not None and v.hand_eye.changed, v.text()
    assert "hand-eye X" in v.moved and 0.07 < v.hand_eye.rotation_deg < 0.13
    assert not any(g.changed for g in v.intrinsics.groups)  # the lens did not change


def test_the_cli_answers_with_exit_codes_and_json(stored: dict, unchanged: tuple, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    res = stored["result"]
    cal = res.calibration
    cam_yaml = write_camera_yaml(tmp_path / "cam.yaml", CameraInfoData(cal.width, cal.height, "cam", cal.K, cal.D,
                                                                        cal.model))
    write_calibration_json(sidecar_path(cam_yaml), record_of_calibration(assess(cal), "cam"))
    he_yaml = write_hand_eye_yaml(tmp_path / "hand_eye.yaml", HandEyeOutcome(res, assess(res.calibration), 0.0).record(
        HandEyeFrames("tool0", "camera_optical_frame", "base_link")))
    _, robot, imgs, names = unchanged
    for im, n in zip(imgs, names, strict=True):
        cv2.imwrite(str(tmp_path / n), im)
    poses = write_poses_yaml(tmp_path / "poses.yaml", "base_link", "tool0", dict(zip(names, robot, strict=True)))
    args = ["verify", "--target", "ring_grid_a4", "--calibration", str(cam_yaml), "--gamma", "2.2",
            "--hand-eye", str(he_yaml), "--poses", str(poses), "--json", str(tmp_path / "v.json"),
            *[str(tmp_path / n) for n in names]]
    assert main(args) == 0, capsys.readouterr()
    assert "verdict: HOLDS" in capsys.readouterr().out
    doc = json.loads((tmp_path / "v.json").read_text())
    assert doc["verdict"] == "holds" and doc["stored_covariance"] and doc["hand_eye"] is not None
    assert main(["verify", "--target", "ring_grid_a4", "--calibration", str(cam_yaml), "--hand-eye", str(he_yaml),
                 str(tmp_path / names[0])]) == 2  # --hand-eye without --poses
    assert main(["verify", "--target", "ring_grid_a4", "--calibration", str(cam_yaml), "--gamma", "2.2",
                 *[str(tmp_path / n) for n in names[:2]]]) == 1  # two views cannot test it
    assert main(["verify", "--target", "ring_grid_a4", "--calibration", str(tmp_path / "nope.yaml"),
                 str(tmp_path / names[0])]) == 2


def test_views_of_another_camera_mode_are_refused(stored: dict, unchanged: tuple) -> None:
    dets, _, _, _ = unchanged
    other = CalibrationRecord(Camera(stored["ref"].camera.K, stored["ref"].camera.D, 800, 600))
    with pytest.raises(VerifyError, match="640x480"):
        verify_calibration(dets, TARGET, other)
