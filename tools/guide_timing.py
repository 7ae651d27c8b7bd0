#!/usr/bin/env python3
"""Time of one guide step at N views, as the node runs it: the person guide's update after a
stored view (:meth:`GuidedLive.update_now`: recalibrate, rank the next views) and an arm's
``~/suggest`` (:func:`workflows.suggest.suggest_for_arm`: hand-eye calibration, arm model, ranking).
Renders one simulated eye-in-hand session (640x480 by default) and times both on its first N views.

    .venv/bin/python tools/guide_timing.py [--target ring_a4] [--views 3 5 10 20 30] [--size 640 480] [--repeat 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pascal_calib_ros.calibrate.options import CalibrationOptions
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.session.guided_live import GuidedLive
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import resolve_target
from pascal_calib_ros.workflows import suggest as suggest_module
from pascal_calib_ros.workflows.suggest import SuggestOptions, suggest_for_arm


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", default="ring_a4")
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5, 10, 20, 30])
    ap.add_argument("--size", type=int, nargs=2, default=[640, 480])
    ap.add_argument("--repeat", type=int, default=1, help="best of this many runs per N")
    args = ap.parse_args()
    target = resolve_target(args.target)
    n_max = max(args.views)
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=n_max, width=args.size[0],
                                             height=args.size[1], k1=-0.1, seed=1))
    dets = [detect_target(img, target) for img in s.images[target.name]]
    print(f"{target.name}, {args.size[0]}x{args.size[1]}, {sum(d.ok for d in dets)}/{n_max} views detected")
    # the arm's call split: the hand-eye estimate it starts with, and the prediction and ranking after it
    estimate_s: list[float] = []
    calibrate_hand_eye = suggest_module.calibrate_hand_eye

    def timed_estimate(*a, **k):  # type: ignore[no-untyped-def]
        t = time.perf_counter()
        out = calibrate_hand_eye(*a, **k)
        estimate_s.append(time.perf_counter() - t)
        return out

    suggest_module.calibrate_hand_eye = timed_estimate  # type: ignore[assignment]
    print(f"{'views':>5} {'person update s':>16} {'arm suggest s':>14} {'of which hand-eye estimate s':>29} "
          f"{'sigma px':>9} {'arm sigma px':>13}")
    for n in args.views:
        person, arm, estimate = [], [], []
        sigma = arm_sigma = float("nan")
        for _ in range(args.repeat):
            g = GuidedLive(target, CalibrationOptions(), goal_sigma_px=0.01)
            t0 = time.perf_counter()
            g.update_now(dets[:n])
            person.append(time.perf_counter() - t0)
            sigma = g.view().sigma_px
            t0 = time.perf_counter()
            doc = suggest_for_arm(dets[:n], list(s.robot_poses[:n]), target,
                                  SuggestOptions(mode="eye_in_hand"), ("base_link", "tool0"))
            arm.append(time.perf_counter() - t0)
            estimate.append(estimate_s[-1])
            arm_sigma = doc["projection_sigma_px"]
        k = int(np.argmin(arm))
        print(f"{n:>5} {min(person):>16.2f} {arm[k]:>14.2f} {estimate[k]:>29.2f} {sigma:>9.4f} {arm_sigma:>13.4f}")
    return 0 if np.isfinite(sigma) else 1


if __name__ == "__main__":
    raise SystemExit(main())
