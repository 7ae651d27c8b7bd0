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
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    spec = SessionSpec(width=width, height=height, views=frames, k1=-0.1, seed=99)
    _, views = render_session_views(resolve_target("ring_a4"), spec)
    payloads = [np.ascontiguousarray(v.image).tobytes() for v in views]
    dom = domain_id if domain_id is not None else random.randint(1, 100)
    node = NodeProcess("calibration_node", {"max_views": 40, "min_views": 8}, dom,
                       log_dir / "load_calibration_node.log")
    client = RosClient(dom, "load_publisher")
    status: list[Any] = []
    try:
        client.node.create_subscription(DiagnosticArray, "/pascal_calib/status", status.append, 10)
        pub = client.node.create_publisher(Image, "/image", QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE,
                                                                       history=HistoryPolicy.KEEP_LAST))
        if not client.spin_until(lambda: pub.get_subscription_count() > 0 and bool(status), 30):
            raise RuntimeError("calibration node did not come up:\n" + node.log())

        def kv() -> dict[str, str]:
            return {v.key: v.value for v in status[-1].status[0].values} if status else {}

        rss: list[tuple[float, float]] = []
        writer = None
        fcsv = open(csv_path, "w", newline="") if csv_path else None
        if fcsv:
            writer = csv.writer(fcsv)
            writer.writerow(["t_s", "published", "received", "dropped", "bad", "views", "rss_mb"])
        t0 = time.monotonic()
        n = 0
        next_sample = t0
        while time.monotonic() - t0 < seconds:
            t_pub = t0 + n / rate
            def due(t_pub: float = t_pub) -> bool:
                return time.monotonic() >= t_pub

            client.spin_until(due, max(0.0, t_pub - time.monotonic()) + 0.1)
            msg = Image(header=Header(frame_id="camera", stamp=client.node.get_clock().now().to_msg()),
                        height=height, width=width, encoding="mono8", is_bigendian=0, step=width)
            msg.data = payloads[n % len(payloads)]
            pub.publish(msg)
            n += 1
            now = time.monotonic()
            if now >= next_sample:
                next_sample = now + 5.0
                m = _rss_mb(node.proc.pid)
                rss.append((now - t0, m))
                s = kv()
                if writer:
                    writer.writerow([f"{now - t0:.1f}", n, s.get("frames_received"), s.get("frames_dropped"),
                                     s.get("frames_bad"), s.get("views_accepted"), f"{m:.1f}"])
                    assert fcsv is not None
                    fcsv.flush()
                if progress:
                    print(f"  t={now - t0:6.0f}s published={n} received={s.get('frames_received')} "
                          f"dropped={s.get('frames_dropped')} rss={m:.0f}MB", flush=True)
        elapsed = time.monotonic() - t0
        client.spin_until(lambda: False, 2.0)  # drain and let the status catch up
        s = kv()
        received, dropped = int(s.get("frames_received", 0)), int(s.get("frames_dropped", 0))
        rss.append((elapsed, _rss_mb(node.proc.pid)))
        if fcsv:
            fcsv.close()
        return LoadResult(elapsed, n, received, dropped, (received - dropped) / elapsed, rss)
    finally:
        client.close()
        node.stop()
