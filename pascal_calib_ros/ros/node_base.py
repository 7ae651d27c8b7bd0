"""What every mode of the calibration node shares (``pascal_calib``: mono, stereo; a rig of N cameras
next): the parameters (declared from one table, checked at start and at every change), the
detector thread that only the newest input waits for, the guarded services and timers, one
calibration at a time with every failed attempt labelled (:mod:`..session.result_history`), and a
clean stop. A mode is a subclass with its interfaces, its input and its calibration."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from ..session import Answer, ResultHistory
from ..targets import Target, resolve_target
from .guard import guarded_callback, guarded_parameters, guarded_service
from .params import ParameterError, declare_parameters, param_value, params_for, validate_parameters

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     history=HistoryPolicy.KEEP_LAST)
Answer = Answer  # a service's success and message


class CalibrationNodeBase(Node):
    """The shared plumbing (module docstring). Subclasses set :attr:`MODE` and implement
    :meth:`apply_changes`, :meth:`process` and :meth:`attempt`."""

    MODE = "mono"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("pascal_calib", **kwargs)
        declare_parameters(self, self.MODE)
        problems = validate_parameters(self.values(), {})
        if problems:
            raise ParameterError("invalid parameters: " + "; ".join(problems))
        self.target: Target = resolve_target(self.p("target"))
        self.add_on_set_parameters_callback(guarded_parameters(self, self._on_set_parameters))
        self.history = ResultHistory()  # the live result's id, the last failed attempt
        self.last_error = ""
        self.calibrating = threading.Lock()
        self.auto_done_at = -1
        self._pending: Any = None
        self._pending_cv = threading.Condition()
        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work, name="detector", daemon=True)

    # -- parameters ------------------------------------------------------------------
    def p(self, name: str) -> Any:
        return param_value(self, name)  # `~` expanded in the paths

    def values(self) -> dict[str, Any]:
        return {p.name: self.p(p.name) for p in params_for(self.MODE)}

    @property
    def method(self) -> str:
        return str(self.p("method") or self.target.default_method())

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in params}
        problems = validate_parameters(changes, self.values())
        if problems:
            return SetParametersResult(successful=False, reason="; ".join(problems))
        if "target" in changes:
            self.target = resolve_target(str(changes["target"]))
        self.apply_changes(changes)
        return SetParametersResult(successful=True)

    def apply_changes(self, changes: dict[str, Any]) -> None:
        """Apply checked parameter changes to the session (a new target: start over)."""
        raise NotImplementedError

    # -- interfaces ------------------------------------------------------------------
    def add_services(self, services: dict[str, Callable[[], Answer]], group: Any) -> None:
        """``~/<name>`` std_srvs/Trigger services answering ``handler()``; what a handler raises is
        answered as a failure with the reason (:func:`.guard.guarded_service`)."""
        for name, handler in services.items():
            def serve(_req: Trigger.Request, resp: Trigger.Response, handler: Callable[[], Answer] = handler
                      ) -> Trigger.Response:
                resp.success, resp.message = handler()
                return resp
            self.create_service(Trigger, f"~/{name}", guarded_service(self, f"~/{name}", serve), callback_group=group)

    def add_timers(self, timers: dict[str, Callable[[], None]], period_s: float = 1.0) -> None:
        """Timers whose exceptions are logged, never raised (:func:`.guard.guarded_callback`)."""
        for what, tick in timers.items():
            self.create_timer(period_s, guarded_callback(self, what, tick),
                              callback_group=MutuallyExclusiveCallbackGroup())

    # -- the detector thread -----------------------------------------------------------
    def hand_over(self, item: Any) -> bool:
        """Give the detector thread its next input (the newest only); True if an unexamined one was
        replaced (dropped). Call with ``_pending_cv`` held or not (it is re-entrant for this)."""
        with self._pending_cv:
            dropped = self._pending is not None
            self._pending = item
            self._pending_cv.notify()
            return dropped

    def _work(self) -> None:
        while not self._stop.is_set():
            with self._pending_cv:
                while self._pending is None and not self._stop.is_set():
                    self._pending_cv.wait(0.2)
                pending, self._pending = self._pending, None
            if pending is None:
                continue
            try:
                self.process(pending)
            except Exception as e:  # bad input must never stop the node
                self.last_error = f"{self.input_name} processing failed: {type(e).__name__}: {e}"
                self.get_logger().error(self.last_error)
            finally:
                self.examined(pending)

    input_name = "frame"

    def process(self, pending: Any) -> None:
        """Detect and collect one input (the detector thread)."""
        raise NotImplementedError

    def examined(self, pending: Any) -> None:
        """Count and acknowledge an examined input, whatever became of it."""
        raise NotImplementedError

    # -- calibration ------------------------------------------------------------------
    def run_calibration(self) -> Answer:
        """One attempt at a time; a failed one is labelled (``~/status``'s ``last_attempt``;
        ``~/commit`` then refuses the older result)."""
        if not self.calibrating.acquire(blocking=False):
            return Answer(False, "a calibration is already running; try again when it finishes")
        try:
            ok, answer = self.attempt()
        except Exception as e:  # never let a numerical failure take the node down
            self.get_logger().error(f"calibration crashed: {type(e).__name__}: {e}")
            ok, answer = False, f"calibration failed: {type(e).__name__}: {e}"
        finally:
            self.calibrating.release()
        if not ok:
            self.history.attempt_failed(answer)
            self.publish_status()
        return Answer(ok, answer)

    def attempt(self) -> Answer:
        """Calibrate the stored views, publish and write a good result (the caller holds the lock)."""
        raise NotImplementedError

    def auto_calibrate(self, ready: bool, count: int) -> None:
        """With ``auto_calibrate``: calibrate in the background once per new count of views."""
        if ready and self.p("auto_calibrate") and self.auto_done_at != count and not self.calibrating.locked():
            self.auto_done_at = count
            threading.Thread(target=self.run_calibration, name="auto-calibrate", daemon=True).start()

    def publish_status(self) -> None:
        raise NotImplementedError

    def log(self, message: str, ok: bool) -> None:
        """Info when ``ok``, else a warning (rclpy wants one severity per call site)."""
        if ok:
            self.get_logger().info(message)
        else:
            self.get_logger().warn(message)

    def start(self) -> None:
        """Start the detector thread (at the end of a subclass's ``__init__``)."""
        self._worker.start()

    def stop(self) -> None:
        """Stop the detector thread (called before the node is destroyed)."""
        self._stop.set()
        with self._pending_cv:
            self._pending_cv.notify_all()
        if self._worker.is_alive():
            self._worker.join(timeout=5.0)
