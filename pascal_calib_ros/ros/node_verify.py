"""``~/verify`` of the calibration node: the views collected since the last ``~/reset`` against the
published calibration (and the hand-eye result), :mod:`..workflows.verify`."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from ..calibrate import CalibrationResult
from ..errors import PascalCalibError
from ..io import CalibrationRecord, read_calibration_file
from ..session import Answer, LiveSession
from ..targets import Target
from ..workflows import hand_eye_reference_of_result, record_of_result, reference_of_file, verify_detections
from .node_parts import NodeCore


class VerifiedNode(NodeCore, Protocol):
    """What ``~/verify`` uses of the node (:class:`.calibration_node.CalibrationNode`)."""

    session: LiveSession
    target: Target
    result: CalibrationResult | None
    hand_eye_result: Any  # (HandEyeResult, parent frame, camera frame) of the last ~/calibrate, or None

    def calibration_path(self) -> Path: ...


def run_verification(node: VerifiedNode) -> Answer:
    """(success when the test could run, the answer starting with the verdict)."""
    snap = node.session.snapshot()
    try:
        reference = verify_reference(node)
    except PascalCalibError as e:
        return Answer(False, f"nothing to verify against: {e}")
    robot, he_ref = None, None
    if node.hand_eye_result is not None:
        he, parent, cam_frame = node.hand_eye_result
        robot = list(snap.robot_poses)
        he_ref = hand_eye_reference_of_result(he, parent, cam_frame, float(node.p("arm_accuracy_mm")),
                                              float(node.p("arm_accuracy_length")))
    try:
        _, line = verify_detections(snap.views, node.target, reference, robot, he_ref)
    except PascalCalibError as e:
        return Answer(False, f"the views cannot test the calibration: {e}")
    except Exception as e:  # never let a numerical failure take the node down
        node.get_logger().error(f"verification crashed: {type(e).__name__}: {e}")
        return Answer(False, f"verification failed: {type(e).__name__}: {e}")
    return Answer(True, line)


def verify_reference(node: VerifiedNode) -> CalibrationRecord:
    """The calibration under test: this session's last result, else the calibration file (with its
    ``.calibration.json`` beside it for the covariance)."""
    if node.result is not None:
        return record_of_result(node.result)
    path = node.calibration_path()
    if not path.exists():
        raise PascalCalibError(f"no calibration in this session and no {path}: call ~/calibrate first")
    return reference_of_file(read_calibration_file(path))
