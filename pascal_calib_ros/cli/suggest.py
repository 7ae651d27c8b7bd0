"""``pascal-calib suggest``: the next views to take (NEXT.yaml) until the projection uncertainty over
the whole image reaches a goal; with ``--poses``, tool poses for a robot arm (the work:
:mod:`..workflows.suggest`). Exit codes: 0, or 2 with the reason on bad input."""

from __future__ import annotations

import argparse

from ..calibrate.handeye.options import HAND_EYE_MODES
from ..calibrate.problem import DISTORTION_MODELS
from ..geometry.transform import Transform
from ..io.hand_eye_yaml import PosesYamlError, read_poses_yaml
from ..io.images import expand_image_args
from ..targets import TargetError, resolve_target
from ..workflows.detection import detect_files, detection_params
from ..workflows.suggest import (
    SuggestError,
    SuggestOptions,
    suggest_for_arm,
    suggest_for_person,
    summary,
    write_next_yaml,
)
from .common import EXIT_INPUT, EXIT_OK, error, progress


def run(args: argparse.Namespace) -> int:
    """The CLI command (exit 0, or 2 with the reason on bad input)."""
    opt = SuggestOptions(n=args.n, goal_sigma_px=args.goal_sigma, distortion=args.distortion, mode=args.mode or "",
                         reach=args.reach, max_turn=args.max_turn, goal_deg=args.goal_deg, goal_mm=args.goal_mm)
    why = opt.problem()
    if not why and bool(args.poses) != bool(args.mode):
        why = "give --poses POSES.yaml and --mode eye_in_hand|eye_to_hand together"
    try:
        if why:
            raise SuggestError(why)
        target = resolve_target(args.target)
        paths = expand_image_args(args.images)
        if not paths:
            raise SuggestError("no images given")
        poses: dict[str, Transform] = {}
        frames = ("", "")
        if args.poses:
            frame_id, child_id, poses = read_poses_yaml(args.poses)
            frames = (frame_id, child_id)
            if not any(p.name in poses for p in paths):
                raise SuggestError(f"no image has a pose in {args.poses} (images are matched by file name, e.g. "
                                   f"{paths[0].name})")
        dets = detect_files(paths, target, detection_params(opt.distortion), progress=progress())
        if args.poses:
            doc = suggest_for_arm(dets, [poses.get(p.name) for p in paths], target, opt, frames)
        else:
            doc = suggest_for_person(dets, target, opt)
    except (SuggestError, TargetError, PosesYamlError) as e:
        error(str(e))
        return EXIT_INPUT
    for d in dets:
        if not d.ok:
            print(f"  rejected  {d.name}  {d.reason}")
    print(summary(doc))
    print(f"wrote {write_next_yaml(args.output, doc)}")
    return EXIT_OK


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``suggest`` with the CLI's subparsers."""
    s = sub.add_parser("suggest", help="the next views to take (NEXT.yaml), until the projection uncertainty over the "
                                       "whole image reaches a goal; with --poses: tool poses for a robot arm")
    s.add_argument("--target", required=True, help="target YAML file or packaged name")
    s.add_argument("--distortion", default="plumb_bob", choices=sorted(DISTORTION_MODELS))
    s.add_argument("--goal-sigma", type=float, default=SuggestOptions.goal_sigma_px, metavar="PX",
                   help="done when the worst projection sigma over the whole image is at most this (px)")
    s.add_argument("-n", type=int, default=SuggestOptions.n, metavar="K", help="at most K suggestions, best first")
    s.add_argument("--poses", help="POSES.yaml: the tool pose in the base frame per image (arm sessions)")
    s.add_argument("--mode", choices=HAND_EYE_MODES, help="with --poses: where the camera is")
    s.add_argument("--reach", type=float, default=SuggestOptions.reach, metavar="M",
                   help="with --poses: suggested tool positions within this many metres of a visited one")
    s.add_argument("--max-turn", type=float, default=SuggestOptions.max_turn, metavar="DEG",
                   help="with --poses: suggested tool orientations within this many degrees of the nearest visited")
    s.add_argument("--goal-deg", type=float, default=SuggestOptions.goal_deg,
                   help="with --poses: done also needs the hand-eye rotation sigma at most this (deg)")
    s.add_argument("--goal-mm", type=float, default=SuggestOptions.goal_mm,
                   help="with --poses: done also needs the hand-eye translation sigma at most this (mm)")
    s.add_argument("-o", "--output", required=True, help="NEXT.yaml path")
    s.add_argument("images", nargs="+", help="image files or folders")
    s.set_defaults(func=run)
