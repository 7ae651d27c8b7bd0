#!/usr/bin/env python3
"""Node throughput across processes (``make bench``, after ``pascal-calib bench``): 5 MP mono8
frames (2456x2058) at 10 Hz over reliable DDS into a fresh calibration node for 30 s; prints the
frames published / received / dropped, the processing rate and the node's memory. ``--streams 2``:
two cameras at once, one node each, on the same cores.
Run: tools/in_netns .venv/bin/python tools/bench_node.py [--seconds 30] [--streams 2] [--json]"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from node_load import run_load_streams


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--size", default="2456x2058")
    ap.add_argument("--streams", type=int, default=1,
                    help="cameras at once: one calibration node per stream, all on this machine")
    ap.add_argument("--json", action="store_true", help='print {"node": {...}} as JSON (a list with --streams > 1)')
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.lower().split("x"))
    loads = run_load_streams(a.seconds, a.streams, rate=a.rate, width=w, height=h)
    rows = [{"size": f"{w}x{h}", "rate_hz": a.rate, "seconds": load.seconds, "published": load.published,
             "received": load.received, "dropped": load.dropped, "processed_per_s": load.processed_per_s,
             "rss_mb_start": load.rss_mb[0][1], "rss_mb_end": load.rss_mb[-1][1]} for load in loads]
    if a.json:
        print(json.dumps({"node": rows[0] if a.streams == 1 else rows}))
    else:
        for k, load in enumerate(loads):
            which = "" if a.streams == 1 else f", stream {k + 1} of {a.streams}"
            print(f"node throughput ({w}x{h} at {a.rate:g} Hz, across processes{which}): " + load.summary())
    return 0


if __name__ == "__main__":
    sys.exit(main())
