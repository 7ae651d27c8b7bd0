"""Core results -> ROS messages (ros/conversions.py): every lens model's CameraInfo."""

import numpy as np
import pytest

from pascal_calib_ros.calibrate.intrinsic.result import CalibrationResult
from pascal_calib_ros.geometry.camera import rectified_projection
from pascal_calib_ros.ros.conversions import camera_info_msg
from pascal_calib_ros.workflows.outputs import camera_info_data


@pytest.mark.parametrize(("choice", "model", "n"), [("plumb_bob", "plumb_bob", 5),
                                                    ("plumb_bob_k3_fixed", "plumb_bob", 5),
                                                    ("rational_polynomial", "rational_polynomial", 8),
                                                    ("equidistant", "equidistant", 4)])
def test_camera_info_carries_the_ros_model_name_and_its_coefficients(choice: str, model: str, n: int) -> None:
    from std_msgs.msg import Header

    K = np.array([[300.0, 0, 320], [0, 301.0, 240], [0, 0, 1]])
    res = CalibrationResult(K, np.linspace(0.01, 0.02, n), 640, 480, "grid", 0.05, {}, 0.1, [],
                            distortion_model=choice)
    msg = camera_info_msg(camera_info_data(res, "cam"), Header())
    assert msg.distortion_model == model and len(msg.d) == n
    P = np.array(msg.p).reshape(3, 4)
    assert np.allclose(P, rectified_projection(res.camera()))
    assert np.allclose(P[:, :3], K) == (model != "equidistant")  # a fisheye's rectified view is its own
