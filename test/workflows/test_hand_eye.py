"""The hand-eye workflow's pieces: which frames by mode, when a result may not be published, the
line that publishes it."""

from __future__ import annotations

import numpy as np

from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.tf_command import static_transform_command
from pascal_calib_ros.modes import HandEyeMode
from pascal_calib_ros.workflows.hand_eye import (
    HandEyeFrames,
    hand_eye_doubts,
    hand_eye_frames,
)


def test_frames_by_mode() -> None:
    assert hand_eye_frames(HandEyeMode.EYE_IN_HAND, "base_link", "tool0", "cam") == HandEyeFrames("tool0", "cam",
                                                                                                   "base_link")
    assert hand_eye_frames(HandEyeMode.EYE_TO_HAND, "base_link", "tool0", "cam") == HandEyeFrames("base_link", "cam",
                                                                                                   "tool0")


def test_static_transform_command_publishes_x() -> None:
    X = Transform.from_rotvec([0.0, 0.0, np.pi / 2], [0.1, -0.02, 0.3])
    line = static_transform_command(X, "tool0", "camera_optical_frame")
    assert line.startswith("ros2 run tf2_ros static_transform_publisher --x 0.100000 --y -0.020000 --z 0.300000")
    assert "--qz 0.7071068 --qw 0.7071068 --frame-id tool0 --child-frame-id camera_optical_frame" in line


def test_hand_eye_doubts() -> None:
    class R:
        hand_eye = Transform.from_rotvec([0, 0, 0.1], [0.04, 0.0, 0.07])
        translation_std_mm = np.array([0.1, 0.1, 0.2])
        rotation_std_deg = np.array([0.01, 0.01, 0.02])

    assert hand_eye_doubts(R()) == []
    R.translation_std_mm = np.array([0.1, 30.0, 0.2])
    assert "translation std up to 30.00 mm" in hand_eye_doubts(R())[0]
    R.rotation_std_deg = np.array([np.nan, 0, 0])
    assert "uncertainty is unknown" in hand_eye_doubts(R())[0]
