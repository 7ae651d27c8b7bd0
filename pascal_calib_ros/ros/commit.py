"""``~/commit``: the last good CameraInfo to the driver's ``sensor_msgs/SetCameraInfo`` service (stereo: each
camera's to its own driver's service)."""

from __future__ import annotations

import threading
from typing import Any

from sensor_msgs.msg import CameraInfo
from sensor_msgs.srv import SetCameraInfo

from ..session import Answer


def commit_camera_info(client: Any, info: CameraInfo | None, timeout_s: float = 10.0) -> Answer:
    """Send ``info`` through ``client`` (a SetCameraInfo client) and say what the driver answered:
    (success, message). Nothing to send, a missing service, no answer within ``timeout_s`` or a
    failed call are refusals with the reason."""
    service = client.srv_name
    if info is None:
        return Answer(False, "no calibration to commit: call ~/calibrate first")
    if not client.wait_for_service(timeout_sec=2.0):
        return Answer(False, f"driver service {service} is not available")
    done = threading.Event()
    fut = client.call_async(SetCameraInfo.Request(camera_info=info))
    fut.add_done_callback(lambda _f: done.set())
    if not done.wait(timeout_s):
        fut.cancel()
        return Answer(False, f"driver service {service} did not answer within {timeout_s:g} s")
    try:
        answer = fut.result()
    except Exception as e:
        return Answer(False, f"driver service {service} failed: {e}")
    if answer is None:
        return Answer(False, f"driver service {service} gave no answer")
    if answer.success:
        return Answer(True, f"driver accepted the calibration: {answer.status_message}")
    return Answer(False, f"driver refused the calibration: {answer.status_message}")


def commit_pair(clients: tuple[Any, Any], infos: tuple[CameraInfo, CameraInfo] | None,
                timeout_s: float = 10.0) -> Answer:
    """A stereo pair's commit: the left CameraInfo to the left driver's own service and the right's
    to the right driver's (never one service for both: it would write both calibrations into one
    camera's file). Both are sent even if the first fails; success only when both drivers accept;
    the message gives both answers, each with its service."""
    if infos is None:
        return Answer(False, "no calibration to commit: call ~/calibrate first")
    if clients[0].srv_name == clients[1].srv_name:
        return Answer(False, f"both cameras would commit to {clients[0].srv_name}: set left_set_camera_info_service "
                             "and right_set_camera_info_service to each driver's own service")
    answers = [commit_camera_info(cli, info, timeout_s) for cli, info in zip(clients, infos, strict=True)]
    text = "; ".join(f"{side} ({cli.srv_name}): {msg}"
                     for side, cli, (_, msg) in zip(("left", "right"), clients, answers, strict=True))
    ok = all(a[0] for a in answers)
    if not ok and any(a[0] for a in answers):
        text += "; only one camera holds the new calibration: fix the other driver and commit again"
    return Answer(ok, text)
