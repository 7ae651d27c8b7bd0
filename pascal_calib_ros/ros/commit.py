"""``~/commit``: the last good CameraInfo to the driver's ``sensor_msgs/SetCameraInfo`` service."""

from __future__ import annotations

import threading
from typing import Any

from sensor_msgs.msg import CameraInfo
from sensor_msgs.srv import SetCameraInfo


def commit_camera_info(client: Any, info: CameraInfo | None, timeout_s: float = 10.0) -> tuple[bool, str]:
    """Send ``info`` through ``client`` (a SetCameraInfo client) and say what the driver answered:
    (success, message). Nothing to send, a missing service, no answer within ``timeout_s`` or a
    failed call are refusals with the reason."""
    service = client.srv_name
    if info is None:
        return False, "no calibration to commit: call ~/calibrate first"
    if not client.wait_for_service(timeout_sec=2.0):
        return False, f"driver service {service} is not available"
    done = threading.Event()
    fut = client.call_async(SetCameraInfo.Request(camera_info=info))
    fut.add_done_callback(lambda _f: done.set())
    if not done.wait(timeout_s):
        fut.cancel()
        return False, f"driver service {service} did not answer within {timeout_s:g} s"
    try:
        answer = fut.result()
    except Exception as e:
        return False, f"driver service {service} failed: {e}"
    if answer is None:
        return False, f"driver service {service} gave no answer"
    if answer.success:
        return True, f"driver accepted the calibration: {answer.status_message}"
    return False, f"driver refused the calibration: {answer.status_message}"
