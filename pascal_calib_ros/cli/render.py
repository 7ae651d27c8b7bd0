"""``pascal-calib render``: a synthetic session with ground truth (:mod:`..sim.session`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..sim import SessionSpec, render_session
from .common import EXIT_INPUT, EXIT_OK, target_or_none


def add_parser(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser("render", help="render a synthetic session with ground truth")
    r.add_argument("--target", default="ring_a4")
    r.add_argument("--out", required=True)
    r.add_argument("--size", default="800x600")
    r.add_argument("--focal", type=float, default=0.0, help="px (default: image width)")
    r.add_argument("--k1", type=float, default=0.0)
    r.add_argument("--lens", default="plumb_bob", choices=("plumb_bob", "rational_polynomial", "equidistant"),
                   help="lens model of the rendered camera (with --dist)")
    r.add_argument("--dist", default="", help="its coefficients, comma-separated, in ROS order (e.g. fisheye: "
                   "--lens equidistant --focal 300 --dist 0.02,-0.005,0.001,-0.0002)")
    r.add_argument("--views", type=int, default=12)
    r.add_argument("--blur", type=float, default=1.0)
    r.add_argument("--gamma", type=float, default=2.2)
    r.add_argument("--noise", type=float, default=1.5)
    r.add_argument("--jpeg", type=int, default=0, help="JPEG quality (0: PNG)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--cut-views", type=int, default=0, help="extra views with the target cut by the frame")
    r.add_argument("--partial-views", type=int, default=0,
                   help="extra views with a marker board hanging partly out of the frame (ChArUco, AprilGrid)")
    r.add_argument("--empty-views", type=int, default=0, help="extra views without any target")
    r.add_argument("--defocused-views", type=int, default=0, help="extra strongly defocused views")
    r.add_argument("--min-size", type=float, default=0.3, help="smallest target extent, fraction of the width")
    r.add_argument("--max-size", type=float, default=0.6, help="largest target extent, fraction of the width")
    r.add_argument("--pitch-ratio", type=float, default=0.0, help="print the sheet's y this much longer (0.003)")
    r.add_argument("--warp-x", type=float, default=0.0, help="bend the sheet along x by this many mm")
    r.add_argument("--warp-y", type=float, default=0.0, help="bend the sheet along y by this many mm")
    r.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    target = target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    w, h = (int(v) for v in args.size.lower().split("x"))
    spec = SessionSpec(width=w, height=h, focal=args.focal, k1=args.k1, views=args.views, blur=args.blur,
                       gamma=args.gamma, noise=args.noise, jpeg=args.jpeg, seed=args.seed,
                       cut_views=args.cut_views, partial_views=args.partial_views, empty_views=args.empty_views,
                       defocused_views=args.defocused_views,
                       size_range=(args.min_size, args.max_size), pitch_ratio=args.pitch_ratio,
                       warp_x=args.warp_x / 1000, warp_y=args.warp_y / 1000, lens=args.lens,
                       dist=tuple(float(v) for v in args.dist.split(",")) if args.dist else (),
                       pixel_range=(0.05, 0.95) if args.lens == "equidistant" else (0.2, 0.8))
    paths = render_session(target, spec, Path(args.out), progress=sys.stderr.isatty())
    print(f"wrote {len(paths)} images and ground truth to {args.out}")
    return EXIT_OK
