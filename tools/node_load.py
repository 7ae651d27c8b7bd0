"""Load the calibration node across processes: publish large frames at a fixed rate and record
the node's processing rate, dropped frames and memory (``tools/bench_node.py`` for ``make bench``,
``tools/soak.py``). Not part of the installed package: import it with tools/ on ``sys.path``."""

from __future__ import annotations

import csv
import random
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from node_processes import NodeProcess, RosClient

from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import resolve_target


@dataclass
class LoadResult:
    seconds: float
    published: int
    received: int
    dropped: int
    processed_per_s: float
    rss_mb: list[tuple[float, float]] = field(default_factory=list)  # (t, MB)

    def summary(self) -> str:
        rss = [m for _, m in self.rss_mb]
        mem = f"RSS {rss[0]:.0f} -> {rss[-1]:.0f} MB (max {max(rss):.0f})" if rss else "RSS n/a"
        return (f"{self.published} frames published in {self.seconds:.0f} s "
                f"({self.published / max(self.seconds, 1e-9):.1f} Hz); node received {self.received}, "
                f"dropped {self.dropped} unprocessed, processed {self.processed_per_s:.1f} frames/s; {mem}")


def _rss_mb(pid: int) -> float:
    """Resident memory of a process and its children (the node's detector process), MB."""
    total = 0.0
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                total += int(line.split()[1]) / 1024
        for task in Path(f"/proc/{pid}/task").iterdir():
            for child in (task / "children").read_text().split():
                total += _rss_mb(int(child))
    except OSError:
        pass
    return total


def run_load(seconds: float, rate: float = 10.0, width: int = 2456, height: int = 2058, frames: int = 12,
             domain_id: int | None = None, log_dir: Path = Path("/tmp"), csv_path: Path | None = None,
             progress: bool = False) -> LoadResult:
    """Publish ``frames`` distinct renders in a loop at ``rate`` Hz for ``seconds`` to a fresh
    calibration node (reliable QoS) and measure it."""
    return run_load_streams(seconds, 1, rate, width, height, frames, domain_id, log_dir, csv_path, progress)[0]


@dataclass
class _Stream:
    """One camera's stream: a calibration node and the client publishing to it, in their own
    ROS domain (two cameras are two nodes on the same machine, sharing its cores)."""

    node: NodeProcess
    client: RosClient
    pub: Any
    status: list[Any]

    def kv(self) -> dict[str, str]:
        return {v.key: v.value for v in self.status[-1].status[0].values} if self.status else {}


def _open_stream(dom: int, log: Path, name: str) -> _Stream:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    node = NodeProcess("calibration_node", {"max_views": 40, "min_views": 8}, dom, log)
    client = RosClient(dom, name)
    status: list[Any] = []
    client.node.create_subscription(DiagnosticArray, "/pascal_calib/status", status.append, 10)
    pub = client.node.create_publisher(Image, "/image", QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE,
                                                                   history=HistoryPolicy.KEEP_LAST))
    return _Stream(node, client, pub, status)


def run_load_streams(seconds: float, streams: int = 1, rate: float = 10.0, width: int = 2456, height: int = 2058,
                     frames: int = 12, domain_id: int | None = None, log_dir: Path = Path("/tmp"),
                     csv_path: Path | None = None, progress: bool = False) -> list[LoadResult]:
    """:func:`run_load` for ``streams`` cameras at once: one calibration node per stream (each in
    its own ROS domain), all fed at ``rate`` Hz from this process; one result per stream (the
    CSV and the progress lines follow the first)."""
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    spec = SessionSpec(width=width, height=height, views=frames, k1=-0.1, seed=99)
    _, views = render_session_views(resolve_target("ring_a4"), spec)
    payloads = [np.ascontiguousarray(v.image).tobytes() for v in views]
    dom = domain_id if domain_id is not None else random.randint(1, 100 - streams)
    opened: list[_Stream] = []
    try:
        for k in range(streams):
            log = log_dir / ("load_calibration_node.log" if streams == 1 else f"load_calibration_node_{k}.log")
            opened.append(_open_stream(dom + k, log, f"load_publisher_{k}"))
        for st in opened:
            if not st.client.spin_until(lambda st=st: st.pub.get_subscription_count() > 0 and bool(st.status), 30):
                raise RuntimeError("calibration node did not come up:\n" + st.node.log())

        def spin_all(until: float) -> None:  # every client's callbacks (status) until a deadline
            while True:
                for st in opened:
                    st.client.executor.spin_once(timeout_sec=0.0)
                if time.monotonic() >= until:
                    return
                time.sleep(min(0.005, max(0.0, until - time.monotonic())))

        rss: list[list[tuple[float, float]]] = [[] for _ in opened]
        writer = None
        fcsv = open(csv_path, "w", newline="") if csv_path else None
        if fcsv:
            writer = csv.writer(fcsv)
            writer.writerow(["t_s", "published", "received", "dropped", "bad", "views", "rss_mb"])
        t0 = time.monotonic()
        n = 0
        next_sample = t0
        while time.monotonic() - t0 < seconds:
            spin_all(t0 + n / rate)
            for k, st in enumerate(opened):
                msg = Image(header=Header(frame_id=f"camera_{k}", stamp=st.client.node.get_clock().now().to_msg()),
                            height=height, width=width, encoding="mono8", is_bigendian=0, step=width)
                msg.data = payloads[(n + 5 * k) % len(payloads)]
                st.pub.publish(msg)
            n += 1
            now = time.monotonic()
            if now >= next_sample:
                next_sample = now + 5.0
                for k, st in enumerate(opened):
                    rss[k].append((now - t0, _rss_mb(st.node.proc.pid)))
                s = opened[0].kv()
                if writer:
                    writer.writerow([f"{now - t0:.1f}", n, s.get("frames_received"), s.get("frames_dropped"),
                                     s.get("frames_bad"), s.get("views_accepted"), f"{rss[0][-1][1]:.1f}"])
                    assert fcsv is not None
                    fcsv.flush()
                if progress:
                    print(f"  t={now - t0:6.0f}s published={n} received={s.get('frames_received')} "
                          f"dropped={s.get('frames_dropped')} rss={rss[0][-1][1]:.0f}MB", flush=True)
        elapsed = time.monotonic() - t0
        spin_all(time.monotonic() + 2.0)  # drain and let the status catch up
        if fcsv:
            fcsv.close()
        out = []
        for k, st in enumerate(opened):
            s = st.kv()
            received, dropped = int(s.get("frames_received", 0)), int(s.get("frames_dropped", 0))
            rss[k].append((elapsed, _rss_mb(st.node.proc.pid)))
            out.append(LoadResult(elapsed, n, received, dropped, (received - dropped) / elapsed, rss[k]))
        return out
    finally:
        for st in opened:
            st.client.close()
            st.node.stop()
