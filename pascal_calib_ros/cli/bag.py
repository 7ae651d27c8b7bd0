"""``pascal-calib bag``: images (and an arm's poses) into a rosbag2 bag, to record once and calibrate later."""

from __future__ import annotations

import argparse
import sys

from ..io.bags import BagError, write_arm_bag, write_image_bag
from ..io.images import ImageReadError, expand_image_args
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
    g.add_argument("images", nargs="+")
    g.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
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
