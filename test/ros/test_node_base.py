"""The plumbing every mode of the calibration node shares (``ros/node_base.py``), on a real
in-process node: an attempt that raises is answered and labelled, a second one while one runs is
refused, a bad parameter change is refused with the reason, a failing input never stops the
detector thread."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from ros_harness import next_domain_id, require_netns

pytestmark = [require_netns, pytest.mark.ros]


def test_attempts_are_labelled_one_at_a_time_and_inputs_survive() -> None:
    import rclpy
    from rclpy.parameter import Parameter

    from pascal_calib_ros.ros.node_base import CalibrationNodeBase

    release = threading.Event()

    class Probe(CalibrationNodeBase):
        MODE = "mono"

        def __init__(self, **kwargs: Any) -> None:
            super().__init__(**kwargs)
            self.seen: list[Any] = []
            self.statuses = 0
            self.start()

        def apply_changes(self, changes: dict[str, Any]) -> None:
            self.seen.append(changes)

        def process(self, pending: Any) -> None:
            if pending == "bad":
                raise ValueError("a corrupt input")

        def examined(self, pending: Any) -> None:
            self.seen.append(pending)

        def attempt(self) -> tuple[bool, str]:
            if not release.wait(10):
                raise RuntimeError("never released")
            raise ZeroDivisionError("float division by zero")

        def publish_status(self) -> None:
            self.statuses += 1

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=next_domain_id())
    node = Probe(context=ctx)
    try:
        answers: list[tuple[bool, str]] = []
        t = threading.Thread(target=lambda: answers.append(node.run_calibration()))
        t.start()
        time.sleep(0.2)
        assert node.run_calibration() == (False, "a calibration is already running; try again when it finishes")
        release.set()
        t.join(10)
        assert answers == [(False, "calibration failed: ZeroDivisionError: float division by zero")]
        assert node.history.status()["last_attempt"].endswith("calibration failed: ZeroDivisionError: float "
                                                              "division by zero") and node.statuses == 1
        refused = node.set_parameters([Parameter("max_views", value=4)])[0]
        assert not refused.successful and "max_views 4 < min_views 8" in refused.reason
        assert node.set_parameters([Parameter("min_views", value=5)])[0].successful and {"min_views": 5} in node.seen
        node.hand_over("bad")
        deadline = time.monotonic() + 5
        while "bad" not in node.seen and time.monotonic() < deadline:
            time.sleep(0.02)
        node.hand_over("good")
        while "good" not in node.seen and time.monotonic() < deadline:
            time.sleep(0.02)
        assert node.seen[-2:] == ["bad", "good"] and "frame processing failed: ValueError" in node.last_error
    finally:
        node.stop()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
