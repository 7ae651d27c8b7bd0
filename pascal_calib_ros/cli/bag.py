"""``pascal-calib bag``: images (and an arm's poses) into a rosbag2 bag, to record once and calibrate later."""

from __future__ import annotations

import argparse
import sys

from ..io import BagError, ImageReadError, expand_image_args, write_arm_bag, write_image_bag
from .common import EXIT_INPUT, EXIT_OK, error


def add_parser(sub: argparse._SubParsersAction) -> None:
    g = sub.add_parser("bag", help="write a folder of images into a rosbag2 bag (record once, calibrate later)")
    g.add_argument("--out", required=True, help="new bag folder")
    g.add_argument("--topic", default="/image")
    g.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3")
    g.add_argument("--compressed", action="store_true", help="store the files' bytes as CompressedImage")
    g.add_argument("--rate", type=float, default=2.0, help="message rate for the recorded timestamps (Hz)")
    g.add_argument("--frame-id", default="camera")
    g.add_argument("--poses", help="POSES.yaml: an arm session; each image is shown for --hold s at --rate Hz "
                                   "with its tool pose published at --pose-rate Hz and at every frame")
    g.add_argument("--pose-topic", default="/tool_pose")
    g.add_argument("--pose-type", choices=["pose", "transform"], default="pose",
                   help="geometry_msgs/PoseStamped or TransformStamped")
    g.add_argument("--hold", type=float, default=1.0, help="with --poses: seconds the arm rests at each pose")
    g.add_argument("--pose-rate", type=float, default=20.0, help="with --poses: pose messages per second")
    g.add_argument("--left", nargs="+", metavar="GLOB", help="a stereo session: the left camera's images (folder, "
                                                             "files or glob; with --right), paired as `pascal-calib "
                                                             "stereo` pairs them")
    g.add_argument("--right", nargs="+", metavar="GLOB", help="a stereo session: the right camera's images")
    g.add_argument("--stereo-topics", nargs=2, default=["/left/image_raw", "/right/image_raw"],
                   metavar=("LEFT", "RIGHT"), help="a stereo session's two image topics")
    g.add_argument("--right-delay", type=float, default=0.0,
                   help="a stereo session: the right frames' stamps this many seconds after the left's (0: "
                        "synchronised cameras)")
    g.add_argument("images", nargs="*")
    g.set_defaults(func=run)


def run_stereo(args: argparse.Namespace) -> int:
    """``--left``/``--right``: a stereo session's two image topics, one shot per pair of files."""
    from ..io import write_stereo_bag
    from ..workflows import PairingError, expand_glob, pair_files

    if args.images or args.poses or not (args.left and args.right):
        error("a stereo bag takes --left and --right (no other images, no --poses)")
        return EXIT_INPUT
    try:
        pairing = pair_files([[q for a in arg for q in expand_glob(a)] for arg in (args.left, args.right)],
                             ["left", "right"])
    except PairingError as e:
        error(str(e))
        return EXIT_INPUT
    pairs = [(lp, rp) for lp, rp in zip(*pairing.paths, strict=True) if lp is not None and rp is not None]
    try:
        out = write_stereo_bag(args.out, [lp for lp, _ in pairs], [rp for _, rp in pairs],
                               topics=tuple(args.stereo_topics), storage=args.storage, compressed=args.compressed,
                               rate=args.rate, right_delay=args.right_delay)
    except (BagError, ImageReadError) as e:
        error(str(e))
        return EXIT_INPUT
    kind = "CompressedImage" if args.compressed else "Image"
    skipped = f"; without a partner (not written): {', '.join(pairing.unmatched)}" if pairing.unmatched else ""
    print(f"wrote {len(pairs)} stereo shot(s) (paired {pairing.how}) as sensor_msgs/{kind} on "
          f"{' and '.join(args.stereo_topics)} to {out} ({args.storage}){skipped}")
    return EXIT_OK


def run(args: argparse.Namespace) -> int:
    if args.left or args.right:
        return run_stereo(args)
    paths = expand_image_args(args.images)
    if not paths:
        print("error: no images given", file=sys.stderr)
        return EXIT_INPUT
    kind = "CompressedImage" if args.compressed else "Image"
    try:
        if args.poses:
            out = write_arm_bag(args.out, paths, args.poses, topic=args.topic, pose_topic=args.pose_topic,
                                storage=args.storage, compressed=args.compressed, rate=args.rate, hold=args.hold,
                                pose_rate=args.pose_rate, frame_id=args.frame_id, pose_type=args.pose_type)
            pose_kind = "PoseStamped" if args.pose_type == "pose" else "TransformStamped"
            print(f"wrote an arm session of {len(paths)} pose(s) to {out} ({args.storage}): sensor_msgs/{kind} on "
                  f"{args.topic} ({args.rate:g} Hz, {args.hold:g} s per pose), geometry_msgs/{pose_kind} on "
                  f"{args.pose_topic} ({args.pose_rate:g} Hz and at every frame)")
            return EXIT_OK
        out = write_image_bag(args.out, paths, args.topic, args.storage, args.compressed, args.rate, args.frame_id)
    except (BagError, ImageReadError) as e:
        error(str(e))
        return EXIT_INPUT
    print(f"wrote {len(paths)} sensor_msgs/{kind} on {args.topic} to {out} ({args.storage})")
    return EXIT_OK
