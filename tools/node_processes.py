"""Start nodes as processes and talk to them from a private Context (there is no ``launch`` or
``ros2`` CLI on PyPI). Used by the demo (tools/demo.py), the end-to-end tests (test/ros_harness.py)
and the node load tests (tools/node_load.py). Not part of the installed package: import it with
tools/ on ``sys.path`` (a script in tools/ has it already)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

BIN = Path(sys.executable).parent
# the nodes' home (results and sessions default to ~/.ros/pascal_calib): one per process that starts
# nodes, never the user's (PASCAL_NODE_HOME overrides it)
NODE_HOME = os.environ.get("PASCAL_NODE_HOME") or tempfile.mkdtemp(prefix="pascal_node_home_")
RESPONSE_MATCH_GRACE = 0.5  # s a new service client waits after the service is ready (see call_trigger)


def ros_env(domain_id: int) -> dict[str, str]:
    """Environment for node processes: own domain, discovery on this host only."""
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               AMENT_PREFIX_PATH=str(BIN.parent), PYTHONUNBUFFERED="1",
               PYTHONFAULTHANDLER="1",  # a crash (e.g. SIGSEGV in native code) prints every thread's stack
               HOME=NODE_HOME)
    env.pop("ROS_STATIC_PEERS", None)
    return env


class NodeProcess:
    """A node executable started with ``--ros-args -p name:=value ...``; stopped with a signal."""

    def __init__(self, exe: str, params: dict[str, Any], domain_id: int, log: Path | None = None):
        args = [str(BIN / exe), "--ros-args"]
        for k, v in params.items():
            val = ("true" if v else "false") if isinstance(v, bool) else str(v)
            args += ["-p", f"{k}:={val}"]
        self.log_path = log
        self._log: IO[str] | None = open(log, "w") if log else None
        self.proc = subprocess.Popen(args, env=ros_env(domain_id), stdout=self._log or subprocess.DEVNULL,
                                     stderr=subprocess.STDOUT)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 15.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self._log:
            self._log.close()
        return int(self.proc.returncode)

    def wait(self, timeout: float) -> int:
        return int(self.proc.wait(timeout))

    def log(self) -> str:
        """The process's output so far, and its exit code once it has exited (a negative code: killed
        by that signal, e.g. -9 after not stopping within ``stop``'s timeout)."""
        if self._log and not self._log.closed:
            self._log.flush()
        text = self.log_path.read_text() if self.log_path else ""
        code = self.proc.poll()
        return text if code is None else f"{text}[exit code {code}]\n"


class RosClient:
    """A node in its own Context and domain, spun by hand (no background thread to outlive it)."""

    def __init__(self, domain_id: int, name: str = "client"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._clients: dict[str, Any] = {}

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return predicate()

    def call_trigger(self, service: str, timeout: float = 60.0) -> Any:
        """Call a std_srvs/Trigger service and return its response. One client per service for the
        whole test: a new client's response reader may not yet be matched by the server's response
        writer when the service already reports ready (Fast DDS then drops the answer), so a new
        client waits RESPONSE_MATCH_GRACE s after it first sees the service."""
        from std_srvs.srv import Trigger

        cli = self._clients.get(service)
        if cli is None:
            cli = self._clients[service] = self.node.create_client(Trigger, service)
            if not self.spin_until(cli.service_is_ready, 20.0):
                raise TimeoutError(f"service {service} not available")
            self.spin_until(lambda: False, RESPONSE_MATCH_GRACE)
        elif not self.spin_until(cli.service_is_ready, 20.0):
            raise TimeoutError(f"service {service} not available")
        fut = cli.call_async(Trigger.Request())
        if not self.spin_until(fut.done, timeout):
            raise TimeoutError(f"no answer from {service} within {timeout} s")
        return fut.result()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)
