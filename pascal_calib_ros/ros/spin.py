"""The one way our node processes run: spin in the main thread, stop cleanly on SIGINT/SIGTERM.

rclpy's own signal handler shuts the context down the moment SIGINT arrives; the node is then
finalised (``destroy_node``) after its context is gone, and rcl / Fast DDS crashed there
(SIGSEGV at exit, about one run in twelve). We install our own handlers instead
(``SignalHandlerOptions.NO``): a signal only asks the spin loop to stop, then the node's threads,
the executor and the node are shut down while the context is still valid, and the context last.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

SPIN_PERIOD = 0.1  # s: the longest a signal waits for the spin loop to see it


def run_node(make_node: Callable[[], Any], errors: tuple[type[BaseException], ...], logger: str,
             make_executor: Callable[[], Executor], args: list[str] | None = None) -> int:
    """Create the node (exit code 2 with the reason if its parameters are refused), spin it in
    this thread until Ctrl-C / SIGTERM / context shutdown, then stop its own threads (``stop()``),
    the executor, the node and, last, the context before returning 0. No thread outlives the
    interpreter."""
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        try:
            node = make_node()
        except errors as e:
            rclpy.logging.get_logger(logger).fatal(str(e))
            rclpy.try_shutdown()
            return 2
        executor = make_executor()
        executor.add_node(node)
        try:
            # the wait inside spin_once is C code: a Python signal handler runs only when it
            # returns, hence the short period
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=SPIN_PERIOD)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:
            if rclpy.ok():
                raise
        finally:
            node.stop()
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown()
        return 0
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
