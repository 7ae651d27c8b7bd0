"""The one way our node processes run: spin in the main thread, stop cleanly on SIGINT/SIGTERM."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.executors import Executor, ExternalShutdownException


def run_node(make_node: Callable[[], Any], errors: tuple[type[BaseException], ...], logger: str,
             make_executor: Callable[[], Executor], args: list[str] | None = None) -> int:
    """Create the node (exit code 2 with the reason if its parameters are refused), spin it in
    this thread until Ctrl-C / SIGTERM / context shutdown, then stop its own threads (``stop()``),
    the executor and the context before returning 0. No thread outlives the interpreter."""
    rclpy.init(args=args)
    try:
        node = make_node()
    except errors as e:
        rclpy.logging.get_logger(logger).fatal(str(e))
        rclpy.try_shutdown()
        return 2
    executor = make_executor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # SIGINT/SIGTERM shut the context down from rclpy's signal handler; a worker of the
        # multi-threaded executor may then meet the invalid context (RCLError) before spin sees
        # the shutdown: that is the same shutdown, not a failure
        if rclpy.ok():
            raise
    finally:
        node.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
