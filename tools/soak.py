#!/usr/bin/env python3
"""Soak test (not in CI): 5 MP frames at 10 Hz into the calibration node for 30 minutes; records
the node's memory and processing rate every 5 s to a CSV. Run: tools/in_netns .venv/bin/python
tools/soak.py --minutes 30 --csv out/soak.csv"""

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from node_load import run_load

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--minutes", type=float, default=30.0)
ap.add_argument("--rate", type=float, default=10.0)
ap.add_argument("--size", default="2456x2058")
ap.add_argument("--csv", default="out/soak.csv")
a = ap.parse_args()
w, h = (int(v) for v in a.size.split("x"))
Path(a.csv).parent.mkdir(parents=True, exist_ok=True)
res = run_load(a.minutes * 60, a.rate, w, h, csv_path=Path(a.csv), log_dir=Path(a.csv).parent, progress=True)
print(res.summary())
