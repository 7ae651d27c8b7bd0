"""Callbacks that cannot end the process.

rclpy's executors re-raise an exception that escapes a callback in the thread that spins, and the
node (with its session) ends. Every service, timer, subscription and parameter callback of the
calibration nodes goes through one of these wrappers instead: an unexpected exception becomes a
failed answer (a service: ``success = False``, the reason in ``message``; a parameter change:
refused with the reason) or, for a timer or a subscription, a logged error; the reason is always
logged with the traceback's last frame, and the node keeps running. A stored frame that cannot be
written (:func:`save_frame`) is logged, counted and named in ``~/status``, never silent.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..io import ImageWriteError, write_image


def _where(e: BaseException) -> str:
    """``file:line in function`` of the frame that raised ``e`` (empty if unknown)."""
    tb = traceback.extract_tb(e.__traceback__)
    if not tb:
        return ""
    f = tb[-1]
    return f" (at {f.filename.rsplit('/', 1)[-1]}:{f.lineno} in {f.name})"


def failure(what: str, e: BaseException) -> str:
    """``<what> failed: <Type>: <message>``: the answer a guarded callback gives."""
    return f"{what} failed: {type(e).__name__}: {e}"


def guarded_service(node: Any, name: str, callback: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    """``callback`` (a service's ``(request, response) -> response``) answering with
    ``success = False`` and the reason in ``message`` when it raises."""
    def call(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except Exception as e:  # an unexpected error must never end the node
            why = failure(name, e)
            node.get_logger().error(why + _where(e))
            if hasattr(response, "success"):
                response.success = False
            if hasattr(response, "message"):
                response.message = why
            return response
    return call


def guarded_callback(node: Any, name: str, callback: Callable[..., Any]) -> Callable[..., None]:
    """``callback`` (a timer's or a subscription's) logging what it raises (at most every 5 s)."""
    def call(*args: Any) -> None:
        try:
            callback(*args)
        except Exception as e:  # an unexpected error must never end the node
            node.get_logger().error(failure(name, e) + _where(e), throttle_duration_sec=5.0)
    return call


def guarded_parameters(node: Any, callback: Callable[[list[Any]], Any]) -> Callable[[list[Any]], Any]:
    """An ``on_set_parameters`` callback refusing the change, with the reason, when it raises."""
    from rcl_interfaces.msg import SetParametersResult

    def call(params: list[Any]) -> Any:
        try:
            return callback(params)
        except Exception as e:  # an unexpected error must never end the node
            why = failure("setting parameters", e)
            node.get_logger().error(why + _where(e))
            return SetParametersResult(successful=False, reason=why)
    return call


def save_frame(node: Any, path: Path, img: Any) -> bool:
    """Write a stored frame; a failure is logged, counted (``node.frames_not_saved``) and kept as
    ``node.last_error`` (both in ``~/status``). True if written."""
    try:
        write_image(path, img)
        return True
    except ImageWriteError as e:
        node.frames_not_saved += 1
        node.last_error = f"frame not saved: {e}"
        node.get_logger().error(node.last_error, throttle_duration_sec=5.0)
        return False
