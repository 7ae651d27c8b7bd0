"""The static transform of a saved result (what the ``publisher`` node broadcasts), and the files it refuses."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from rig_sessions import write_rig_file

from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.rectify import rectify_pair
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.hand_eye_yaml import HandEyeRecord, write_hand_eye_yaml
from pascal_calib_ros.io.stereo_yaml import StereoData, write_stereo_yaml
from pascal_calib_ros.workflows.static_transform import ResultFileError, read_result_transform

X = Transform.from_rotvec([0.1, -0.2, 0.3], [0.05, -0.02, 0.11])


def hand_eye_record(**changes: object) -> HandEyeRecord:
    r = HandEyeRecord("eye_in_hand", "tool0", "camera_optical_frame", X, (0.2, 0.3, 0.25), (0.01, 0.02, 0.015),
                      "base_link", Transform.from_rotvec([0, 0, 0.5], [0.6, 0.1, 0.0]), 12, 0.08)
    return replace(r, **changes)  # type: ignore[arg-type]


def test_hand_eye_file_gives_its_transform_and_frames(tmp_path: Path) -> None:
    st = read_result_transform(write_hand_eye_yaml(tmp_path / "hand_eye.yaml", hand_eye_record()))
    assert (st.parent, st.child, st.kind) == ("tool0", "camera_optical_frame", "hand_eye eye_in_hand")
    np.testing.assert_allclose(st.pose.matrix, X.matrix, atol=1e-15)
    assert st.describe().startswith("hand_eye eye_in_hand: tool0 -> camera_optical_frame t=[0.050000, -0.020000")


@pytest.mark.parametrize(("changes", "why"), [
    ({"translation_std_mm": (0.2, 6.0, 0.1)}, "translation std up to 6.00 mm (> 5 mm)"),
    ({"rotation_std_deg": (0.01, 0.02, 0.7)}, "rotation std up to 0.700 deg (> 0.5 deg)"),
    ({"rotation_std_deg": (0.01, float("nan"), 0.1)}, "rotation_std_deg is not finite"),
    ({"child_frame": ""}, "child_frame is missing or empty"),
])
def test_hand_eye_file_the_node_would_not_publish_is_refused(tmp_path: Path, changes: dict, why: str) -> None:
    p = write_hand_eye_yaml(tmp_path / "hand_eye.yaml", hand_eye_record(**changes))
    with pytest.raises(ResultFileError, match=why.replace("(", r"\(").replace(")", r"\)")):
        read_result_transform(p)


def test_hand_eye_file_without_sigmas_or_with_a_bad_quaternion_is_refused(tmp_path: Path) -> None:
    doc = hand_eye_record().document()
    del doc["translation_std_mm"]
    p = tmp_path / "a.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(ResultFileError, match="translation_std_mm is missing"):
        read_result_transform(p)
    doc = hand_eye_record().document()
    doc["rotation"] = [0.0, 0.0, 0.0, 0.5]
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(ResultFileError, match="is not a unit quaternion"):
        read_result_transform(p)
    p.write_text("just: text\n")
    with pytest.raises(ResultFileError, match="neither a hand-eye result"):
        read_result_transform(p)
    with pytest.raises(ResultFileError, match="cannot read"):
        read_result_transform(tmp_path / "missing.yaml")


def _stereo(tmp_path: Path, epipolar_rms: float = 0.02, sigma_mm: float = 0.05) -> tuple[Path, Transform]:
    left = Camera.from_params(640, 641, 322, 238, width=640, height=480)
    right = Camera.from_params(643, 644, 316, 243, width=640, height=480)
    rig = Transform.from_rotvec([0.001, 0.034, 0.002], [-0.12, -0.001, 0.005])
    rect = rectify_pair(left, right, rig.R, rig.translation)
    s_deg, s_mm = np.array([1e-3, 2e-3, 3e-4]), np.array([0.01, 0.02, sigma_mm])
    d = StereoData("head/left", "head/right", "l_frame", "r_frame", 640, 480, rig, s_deg, s_mm, s_deg, s_mm,
                   epipolar_rms, rect)
    return write_stereo_yaml(tmp_path / "stereo.yaml", d), rig


def test_stereo_file_gives_the_right_frame_in_the_left(tmp_path: Path) -> None:
    p, rig = _stereo(tmp_path)
    st = read_result_transform(p)
    assert (st.parent, st.child, st.kind) == ("l_frame", "r_frame", "stereo")
    # p_left = R' p_right + t': the inverse of X_right = R X_left + T, as ~/stereo_transform
    np.testing.assert_allclose(st.pose.matrix, np.linalg.inv(rig.matrix), atol=1e-12)
    doc = yaml.safe_load(p.read_text())["right_in_left"]
    np.testing.assert_allclose(st.pose.translation, doc["translation"], atol=1e-12)


def test_stereo_file_the_node_would_not_publish_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ResultFileError, match=r"epipolar RMS 1\.500 px \(limit 1\.0 px\)"):
        read_result_transform(_stereo(tmp_path, epipolar_rms=1.5)[0])
    with pytest.raises(ResultFileError, match="not determined well enough"):
        read_result_transform(_stereo(tmp_path, sigma_mm=6.0)[0])


def test_a_rig_gives_one_transform_per_camera_or_none(tmp_path: Path) -> None:
    from pascal_calib_ros.workflows.static_transform import read_result_transforms

    sts = read_result_transforms(write_rig_file(tmp_path))
    assert [(st.parent, st.child, st.kind) for st in sts] == [("cam0_optical_frame", "cam1_optical_frame", "rig"),
                                                             ("cam0_optical_frame", "cam2_optical_frame", "rig")]
    np.testing.assert_allclose(sts[1].pose.translation, [0.2, 0.0, 0.0], atol=1e-12)
    with pytest.raises(ResultFileError, match="camera cam1's pose is not determined well enough"):
        read_result_transforms(write_rig_file(tmp_path, sigma_deg=0.9))
    assert len(read_result_transforms(write_hand_eye_yaml(tmp_path / "he.yaml", hand_eye_record()))) == 1
