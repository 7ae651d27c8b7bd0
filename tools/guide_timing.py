#!/usr/bin/env python3
"""Time of one guide step at N views, as the node runs it: the person guide's update after a
stored view (:meth:`GuidedLive.update_now`: recalibrate, rank the next views; cold, and warm after
the update at N - 1 views) and an arm's
``~/suggest`` (:func:`workflows.suggest.suggest_for_arm`: hand-eye calibration, arm model, ranking),
cold (the CLI, the first call) and warm (the node's sequence: the call at N - 1 views, then the
timed one at N, :class:`~pascal_calib_ros.workflows.suggest.WarmArmSuggestions`), each with the
hand-eye estimate it starts with split out, and how far the warm estimate is from the cold one.
Renders one simulated eye-in-hand session (640x480 by default) and times the calls on its first N
views, best of ``--repeat``.

``--before DIR``: the cold arm call of another checkout (say the main branch) on the same
detections, in a child process with ``PYTHONPATH=DIR``, run before this code's calls at each N:
both in the same run, on the same load.

    OMP_NUM_THREADS=1 .venv/bin/python tools/guide_timing.py [--target ring_a4] [--views 3 5 10 20 30]
        [--size 640 480] [--repeat 1] [--before /path/to/other/checkout]
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.session.guided_live import GuidedLive
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import resolve_target
from pascal_calib_ros.workflows import suggest as suggest_module
from pascal_calib_ros.workflows.suggest import SuggestOptions, WarmArmSuggestions, suggest_for_arm

# the other checkout's cold arm call, timed in a child process on the pickled detections: argv = pickle, target,
# views, repeat; prints {"n": [call s, estimate s]} (best call of the repeats)
BEFORE = r"""
import json, pickle, sys, time
from pascal_calib_ros.targets import resolve_target
from pascal_calib_ros.workflows import suggest as sm
dets, robot = pickle.load(open(sys.argv[1], "rb"))
target, out = resolve_target(sys.argv[2]), {}
estimate = []
name = "calibrate_hand_eye_warm" if hasattr(sm, "calibrate_hand_eye_warm") else "calibrate_hand_eye"
wrapped = getattr(sm, name)
def timed(*a, **k):
    t = time.perf_counter()
    r = wrapped(*a, **k)
    estimate.append(time.perf_counter() - t)
    return r
setattr(sm, name, timed)
for n in map(int, sys.argv[3].split(",")):
    best = None
    for _ in range(int(sys.argv[4])):
        t = time.perf_counter()
        sm.suggest_for_arm(dets[:n], robot[:n], target, sm.SuggestOptions(mode="eye_in_hand"), ("base_link", "tool0"))
        run = [time.perf_counter() - t, estimate[-1]]
        best = run if best is None or run[0] < best[0] else best
    out[n] = best
print(json.dumps(out))
"""


class EstimateTimer:
    """Wraps the hand-eye estimate the arm call starts with and keeps its last duration and result."""

    def __init__(self) -> None:
        self.seconds = float("nan")
        self.result: Any = None
        self._wrapped = suggest_module.calibrate_hand_eye_warm

    def __call__(self, *a: Any, **k: Any) -> Any:
        t = time.perf_counter()
        out = self._wrapped(*a, **k)
        self.seconds = time.perf_counter() - t
        self.result = out[0]
        return out


def best_of(repeat: int, run: Callable[[], tuple[float, float, Any]]) -> tuple[float, float, Any]:
    """The fastest of ``repeat`` runs of ``run`` (-> call s, estimate s, hand-eye result)."""
    return min((run() for _ in range(repeat)), key=lambda r: r[0])


def before_times(before: str, data: Path, target: str, views: list[int], repeat: int) -> dict[int, list[float]]:
    env = dict(os.environ, PYTHONPATH=before)
    out = subprocess.run([sys.executable, "-c", BEFORE, str(data), target, ",".join(map(str, views)), str(repeat)],
                         env=env, capture_output=True, text=True, check=True, cwd=before)
    return {int(k): v for k, v in json.loads(out.stdout.strip().splitlines()[-1]).items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", default="ring_a4")
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5, 10, 20, 30])
    ap.add_argument("--size", type=int, nargs=2, default=[640, 480])
    ap.add_argument("--repeat", type=int, default=1, help="best of this many runs per N")
    ap.add_argument("--before", default="", help="another checkout whose cold arm call is timed alongside")
    args = ap.parse_args()
    target = resolve_target(args.target)
    n_max = max(args.views)
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=n_max, width=args.size[0],
                                             height=args.size[1], k1=-0.1, seed=1))
    dets = [detect_target(img, target) for img in s.images[target.name]]
    robot = list(s.robot_poses)
    print(f"{target.name}, {args.size[0]}x{args.size[1]}, {sum(d.ok for d in dets)}/{n_max} views detected, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, best of {args.repeat}; times in s")
    timer = EstimateTimer()
    suggest_module.calibrate_hand_eye_warm = timer  # type: ignore[assignment]
    opt, frames = SuggestOptions(mode="eye_in_hand"), ("base_link", "tool0")

    def cold(n: int) -> tuple[float, float, Any]:
        t = time.perf_counter()
        suggest_for_arm(dets[:n], robot[:n], target, opt, frames)
        return time.perf_counter() - t, timer.seconds, timer.result

    def warm(n: int) -> tuple[float, float, Any]:
        guide = WarmArmSuggestions()
        guide.suggest(dets[:n - 1], robot[:n - 1], target, opt, frames)  # the call after the previous capture
        t = time.perf_counter()
        guide.suggest(dets[:n], robot[:n], target, opt, frames)
        return time.perf_counter() - t, timer.seconds, timer.result

    data = Path(tempfile.mkdtemp()) / "session.pkl"
    data.write_bytes(pickle.dumps((dets, robot)))
    head = (f"{'views':>5} {'person':>7} {'warm':>5} {'arm cold':>9} {'(estimate)':>10} {'arm warm':>9} "
            f"{'(estimate)':>10}")
    print(head + (f" {'before':>7} {'(estimate)':>10} {'cold x':>7} {'warm x':>7}" if args.before else "")
          + f" {'warm-cold: K px':>16} {'X mm':>8} {'X deg':>8}")
    for n in args.views:
        old = before_times(args.before, data, target.name, [n], args.repeat)[n] if args.before else None
        person, person_warm = [], []
        for _ in range(args.repeat):
            g = GuidedLive(target, CalibrationOptions(), goal_sigma_px=0.01)
            t0 = time.perf_counter()
            g.update_now(dets[:n])
            person.append(time.perf_counter() - t0)
            g = GuidedLive(target, CalibrationOptions(), goal_sigma_px=0.01)
            g.update_now(dets[:n - 1])  # the update after the previous stored view
            t0 = time.perf_counter()
            g.update_now(dets[:n])
            person_warm.append(time.perf_counter() - t0)
        c, w = best_of(args.repeat, lambda n=n: cold(n)), best_of(args.repeat, lambda n=n: warm(n))
        hc, hw = c[2], w[2]
        dK = float(np.abs(hw.calibration.K - hc.calibration.K).max())
        dX = 1000 * float(np.abs(hw.hand_eye.translation - hc.hand_eye.translation).max())
        dR = float(np.degrees((hw.hand_eye.rotation * hc.hand_eye.rotation.inv()).magnitude()))
        line = (f"{n:>5} {min(person):>7.2f} {min(person_warm):>5.2f} {c[0]:>9.2f} {c[1]:>10.2f} {w[0]:>9.2f} "
                f"{w[1]:>10.2f}")
        if old is not None:
            line += f" {old[0]:>7.2f} {old[1]:>10.2f} {old[0] / c[0]:>7.1f} {old[0] / w[0]:>7.1f}"
        print(line + f" {dK:>16.1e} {dX:>8.1e} {dR:>8.1e}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
