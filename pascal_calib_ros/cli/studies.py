"""``pascal-calib bench``, ``experiment`` and ``study``: timings, the seed paper's experiments and the
accuracy studies (:mod:`..studies`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .common import EXIT_OK


def add_parser(sub: argparse._SubParsersAction) -> None:
    b = sub.add_parser("bench", help="timings: detection of every shipped target at 800x600, 1920x1080 and "
                                     "2456x2058 (and vs cv2.Canny), calibration vs view count")
    b.add_argument("--json", action="store_true")
    b.add_argument("--quick", action="store_true", help="fewer repetitions")
    b.set_defaults(func=cmd_bench)
    e = sub.add_parser("experiment", help="the seed paper's experiments: CSV + PNG + table")
    e.add_argument("name", choices=["layouts", "methods", "literal", "board", "reconstruct"])
    e.add_argument("--out", default="out/experiments")
    e.add_argument("--trials", type=int, default=None,
                   help="default: 50 (simulations), 3 sessions (board, reconstruct)")
    e.add_argument("--seed", type=int, default=0)
    e.set_defaults(func=cmd_experiment)
    s = sub.add_parser("study", help="accuracy studies against ground truth (see README)")
    s.add_argument("name", choices=["accuracy", "edge-bias", "grids", "target-shape", "lenses", "handeye", "trust",
                                        "model-bias", "verify", "stereo", "guided", "boards", "undesigned"])
    s.add_argument("--sessions", type=int, default=None,
                   help="verify: verification sessions per scenario (default 20); stereo: sessions of the accuracy "
                        "table (default 5)")
    s.add_argument("--draws", type=int, default=None,
                   help="trust, stereo: noise draws and new sessions per scenario (default 10); guided: the arm "
                        "sessions' views shot again under this many fresh noise draws (default 0: none)")
    s.add_argument("--only", default="", help="trust: only the scenarios whose name contains this text; verify: "
                                              "camera, hand-eye and/or timing; guided: ring, grid, board, fisheye, "
                                              "charuco, wide, arm, timing and/or tilt (comma-separated)")
    s.add_argument("--opencv4-python", default="", help="handeye: a Python with OpenCV 4.x for calibrateHandEye")
    s.add_argument("--targets", default="ring_a4,checkerboard_a4", help="handeye: targets, comma-separated")
    s.add_argument("--arm-systematic-mm", type=float, default=0.25,
                   help="handeye: amplitude of the arm's systematic position error field (0: random arm noise only)")
    s.add_argument("--seeds", type=int, default=None, help="guided: sessions per case and strategy (default 20); "
                                                           "undesigned: sessions, seeds 1..N (default 3)")
    s.add_argument("--arm-cell", default="study", choices=["study", "arm"],
                   help="guided, arm case: the cell's noise (study: sensor noise 1.5, arm 0.01 deg / 0.1 mm; arm: "
                        "0.5, 0.03 deg / 0.3 mm, the arm's share dominant)")
    s.add_argument("--arm-guide", default="shipped",
                   choices=["shipped", "narrow", "bias", "bias-no-kappa", "spread", "wide", "wide-spread"],
                   help="guided, arm case: the guide's variant (docs/guided-sessions.md, issue 36)")
    s.add_argument("--quick", action="store_true", help="guided: 640x480 renders")
    s.add_argument("--jobs", type=int, default=2, help="guided: sessions run in parallel")
    s.add_argument("--out", default="out/study")
    s.add_argument("--views", type=int, default=None, help="default: 15 (lenses: 20 per lens)")
    s.add_argument("--seed", type=int, default=1)
    s.set_defaults(func=cmd_study)


def cmd_bench(args: argparse.Namespace) -> int:
    from ..studies import run_bench

    result: dict[str, Any] = dict(run_bench(quick=args.quick, print_table=not args.json))
    if args.json:
        print(json.dumps(result))
    return EXIT_OK


def cmd_study(args: argparse.Namespace) -> int:
    if args.name == "handeye":
        from ..studies import run_handeye_study

        run_handeye_study(Path(args.out), views=args.views or 20, seed=args.seed, opencv4_python=args.opencv4_python,
                          targets=tuple(args.targets.split(",")), systematic_mm=args.arm_systematic_mm)
        return EXIT_OK
    if args.name == "guided":
        from ..studies import run_guided_study

        run_guided_study(Path(args.out), seeds=args.seeds or 20, quick=args.quick, only=args.only, jobs=args.jobs,
                         draws=args.draws or 0, arm=(args.arm_cell, args.arm_guide))
        return EXIT_OK
    if args.name == "trust":
        from ..studies import trust

        trust(Path(args.out), draws=args.draws or 10, views=args.views or 12, only=args.only)
        return EXIT_OK
    if args.name == "verify":
        from ..studies import StudySpec, verify_study

        parts = {"camera", "hand-eye", "timing"} if not args.only else set(args.only.split(","))
        verify_study(Path(args.out), StudySpec(sessions=args.sessions or 20, views=args.views or 10, seed=args.seed,
                                               camera="camera" in parts, hand_eye="hand-eye" in parts,
                                               timing="timing" in parts))
        return EXIT_OK
    if args.name == "model-bias":
        from ..studies import model_bias_study

        model_bias_study(Path(args.out), views=args.views or 12)
        return EXIT_OK
    if args.name == "stereo":
        from ..studies import stereo_study

        stereo_study(Path(args.out), args.views or 15, args.seed, args.draws or 10, args.sessions or 5)
        return EXIT_OK
    if args.name == "boards":
        from ..studies import boards_study

        boards_study(Path(args.out), views=args.views or 12, seed=args.seed)
        return EXIT_OK
    if args.name == "undesigned":
        from ..studies import undesigned_views

        found = undesigned_views(tuple(range(1, (args.seeds or 3) + 1)), views=args.views or 16)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "undesigned_views.json").write_text(json.dumps(found, indent=1, default=str) + "\n")
        return EXIT_OK
    from ..studies import run_study

    run_study(args.name, Path(args.out), views=args.views, seed=args.seed)
    return EXIT_OK


def cmd_experiment(args: argparse.Namespace) -> int:
    from ..studies import run_experiment

    run_experiment(args.name, Path(args.out), args.trials, args.seed)
    return EXIT_OK
