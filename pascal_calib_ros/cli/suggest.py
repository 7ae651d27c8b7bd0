"""``pascal-calib suggest``: the next views to take (NEXT.yaml) until the projection uncertainty over
the whole image reaches a goal; with ``--poses``, tool poses for a robot arm (the work:
:mod:`..workflows.suggest`). Exit codes: 0, or 2 with the reason on bad input.

Refused images are listed with the detector's reason. ``--previous NEXT.yaml`` (the previous call's
output) carries its ``avoided`` placements on, and when the newest image (latest modification time)
was refused, its first suggestion joins them: the view taken there could not be measured, so
nothing in its neighbourhood is suggested again."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..calibrate import DISTORTION_MODELS
from ..detect import Detection
from ..geometry import Placement, Transform
from ..io import (
    NextYamlError,
    PosesYamlError,
    Suggestions,
    expand_image_args,
    read_next_yaml,
    read_poses_yaml,
    write_next_yaml,
)
from ..modes import HandEyeMode
from ..targets import TargetError, resolve_target
from ..workflows import (
    SuggestError,
    SuggestOptions,
    detect_files,
    detection_params,
    suggest_for_arm,
    suggest_for_person,
    summary,
)
from .common import EXIT_INPUT, EXIT_OK, error, progress


def read_previous(path: str) -> Suggestions:
    """The previous call's NEXT.yaml (a :class:`SuggestError` when it cannot be read)."""
    try:
        return read_next_yaml(path)
    except NextYamlError as e:
        raise SuggestError(f"--previous {e}") from None


def avoided_placements(previous: Suggestions | None, paths: list[Path], dets: list[Detection]
                       ) -> tuple[list[Placement], str]:
    """The placements to avoid (module docstring) and a line saying what was added ("" if nothing)."""
    if previous is None:
        return [], ""
    avoid = list(previous.avoided)
    newest = max(range(len(paths)), key=lambda k: (paths[k].stat().st_mtime, k))
    if dets[newest].ok or previous.first is None:
        return avoid, ""
    p = previous.first.placement
    avoid.append(p)
    return avoid, (f"the newest image {paths[newest].name} was refused ({dets[newest].reason}): the previous "
                   f"suggestion 1 (centre at pixel ({p.pixel[0]:.0f}, {p.pixel[1]:.0f}), {p.distance:.2f} "
                   f"m, tilted {p.tilt_deg:.0f} deg) and its neighbourhood are no longer suggested")


def run(args: argparse.Namespace) -> int:
    """The CLI command (exit 0, or 2 with the reason on bad input)."""
    opt = SuggestOptions(n=args.n, goal_sigma_px=args.goal_sigma, distortion=args.distortion,
                         mode=HandEyeMode(args.mode) if args.mode else None,
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
        previous = read_previous(args.previous) if args.previous else None
        dets = detect_files(paths, target, detection_params(opt.distortion), progress=progress())
        avoid, note = avoided_placements(previous, paths, dets)
        if args.poses:
            found = suggest_for_arm(dets, [poses.get(p.name) for p in paths], target, opt, frames, avoid)
        else:
            found = suggest_for_person(dets, target, opt, avoid)
    except (SuggestError, TargetError, PosesYamlError) as e:
        error(str(e))
        return EXIT_INPUT
    for d in dets:
        if not d.ok:
            print(f"  rejected  {d.name}  {d.reason}")
    if note:
        print(note)
    print(summary(found))
    print(f"wrote {write_next_yaml(args.output, found)}")
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
    s.add_argument("--mode", choices=[m.value for m in HandEyeMode], help="with --poses: where the camera is")
    s.add_argument("--reach", type=float, default=SuggestOptions.reach, metavar="M",
                   help="with --poses: suggested tool positions within this many metres of a visited one")
    s.add_argument("--max-turn", type=float, default=SuggestOptions.max_turn, metavar="DEG",
                   help="with --poses: suggested tool orientations within this many degrees of the nearest visited")
    s.add_argument("--goal-deg", type=float, default=SuggestOptions.goal_deg,
                   help="with --poses: done also needs the hand-eye rotation sigma at most this (deg)")
    s.add_argument("--goal-mm", type=float, default=SuggestOptions.goal_mm,
                   help="with --poses: done also needs the hand-eye translation sigma at most this (mm)")
    s.add_argument("--previous", metavar="NEXT.yaml",
                   help="the previous call's NEXT.yaml: its avoided placements are kept, and when the newest image "
                        "(latest modification time) was refused, its first suggestion is avoided too")
    s.add_argument("-o", "--output", required=True, help="NEXT.yaml path")
    s.add_argument("images", nargs="+", help="image files or folders")
    s.set_defaults(func=run)
