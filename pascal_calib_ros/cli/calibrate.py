"""``pascal-calib calibrate``: images in, the camera YAML out (and the report, the cross-validation)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..calibrate import DISTORTION_MODELS, METHODS, OUTLIER_K, SHAPE_CHOICES, CalibrationError, CalibrationOptions
from ..report import format_summary, projection_line
from ..workflows import ResultPaths, detect_files, detection_params, run_intrinsic
from .common import (
    EXIT_CALIB,
    EXIT_INPUT,
    EXIT_OK,
    distance_arg,
    error,
    image_paths_or_none,
    progress,
    session_defaults,
    target_or_none,
    write_result,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    c = sub.add_parser("calibrate", help="calibrate from image files; writes camera_calibration_parsers YAML")
    c.add_argument("--target", help="target YAML file or packaged name (ring_a4, pascal_board_a3); default: the "
                                     "recorded session's")
    c.add_argument("--method", choices=METHODS, help="default: the target's natural method (ring for a ring)")
    c.add_argument("--camera-name", default=None, help="default: camera (a session: its camera name)")
    c.add_argument("-o", "--output", required=True, help="output YAML path")
    c.add_argument("--distortion", default=None, choices=sorted(DISTORTION_MODELS),
                   help="default: plumb_bob (a session: the model it was recorded with)")
    c.add_argument("--no-refine", action="store_true",
                   help="closed form only (no distortion); with --method zhang: OpenCV's calibrateCamera as it is")
    c.add_argument("--loss", default="soft_l1", choices=("soft_l1", "linear"),
                   help="the refinement's loss: soft_l1 (robust, 0.3 px scale; default) or linear (least squares)")
    c.add_argument("--no-outlier-rejection", action="store_true",
                   help="keep every edge point and corner (default: drop those beyond 5 robust sigmas of their view)")
    c.add_argument("--distance", type=distance_arg, default=None, metavar="M|inf",
                   help="evaluate the projection uncertainty for points this far away (m, or inf); default: the "
                        "median distance from the camera to the observed target's centre")
    c.add_argument("--no-edge-offset", action="store_true", help="do not estimate the per-view edge offset")
    c.add_argument("--skew", action="store_true", help="estimate skew (default: zero skew)")
    c.add_argument("--gamma", type=float, default=None,
                   help="linearise with this display gamma before edges (default 1; a session: its gamma)")
    c.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    c.add_argument("--min-views", type=int, default=3)
    c.add_argument("--target-shape", nargs="?", const="warp", choices=[k for k in SHAPE_CHOICES if k],
                   help="also estimate the printed sheet's shape (grids, checkerboards): warp (parabolic "
                        "out-of-plane bend; the default), pitch (y/x scale ratio) or all")
    c.add_argument("--report", metavar="DIR", help="write report.pdf (7 pages), report.png and report.json into DIR")
    c.add_argument("--cross-validate", action="store_true",
                   help="also calibrate two interleaved halves of the views and compare them against their "
                        "projection uncertainty (a model error shows as a larger difference; needs 2 x --min-views "
                        "usable views)")
    c.add_argument("images", nargs="+", help="image files or folders, or a session folder recorded by the node "
                                             "(its frames and settings; docs/nodes.md, Sessions)")
    c.set_defaults(func=run)


def options_of(args: argparse.Namespace, method: str) -> CalibrationOptions:
    """The calibration options a command line asks for."""
    return CalibrationOptions(method=method, refine=not args.no_refine, distortion=args.distortion,
                              zero_skew=not args.skew, edge_offsets=not args.no_edge_offset,
                              min_views=args.min_views, target_shape=SHAPE_CHOICES[args.target_shape or ""],
                              loss=args.loss, outlier_k=0.0 if args.no_outlier_rejection else OUTLIER_K)


def run(args: argparse.Namespace) -> int:
    if session_defaults(args) is False:
        return EXIT_INPUT
    if args.target is None:
        error("--target is required (unless the images are a recorded session folder)")
        return EXIT_INPUT
    target = target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    method = args.method or target.default_method()
    if not args.method:
        print(f"method: {method} (default for target {target.name})")
    paths = image_paths_or_none(args.images)
    if paths is None:
        return EXIT_INPUT
    t0 = time.perf_counter()
    dets = detect_files(paths, target, detection_params(args.distortion, args.gamma, args.max_blur), progress())
    t_detect = time.perf_counter() - t0
    try:
        out = run_intrinsic(dets, target, options_of(args, method), distance=args.distance,
                            with_cross_validation=args.cross_validate)
    except CalibrationError as e:
        for d in dets:
            if not d.ok:
                print(f"  rejected  {d.name}  {d.reason}")
        error(f"calibration failed: {e}")
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    a = out.assessment
    print(format_summary(a))
    print(projection_line(a))
    print(f"time: detection {t_detect:.2f} s ({len(paths)} images), calibration {out.seconds:.2f} s")
    write_result(out.write, ResultPaths(Path(args.output), report_dir=Path(args.report) if args.report else None),
                 args.camera_name, dets, paths)
    for line in out.cross_validation_lines:  # a disagreement or a refusal is a WARNING, not a failure
        print(line)
    return EXIT_OK
