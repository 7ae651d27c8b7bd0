"""``pascal-calib handeye``: images and POSES.yaml (or an arm session bag) in; the camera YAML and
HAND_EYE.yaml out, with the line that publishes the transform."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..calibrate import DISTORTION_MODELS, METHODS, CalibrationError, CalibrationOptions
from ..calibrate.handeye import HandEyeOptions
from ..detect import Detection, DetectionParams
from ..geometry import Transform
from ..io import BagError, PosesYamlError, SessionFolder, read_poses_yaml, static_transform_command
from ..report import format_summary, hand_eye_summary
from ..session import read_arm_bag
from ..targets import Target
from ..workflows import (
    HAND_EYE_FILE,
    ResultPaths,
    detect_files,
    detect_images,
    detection_params,
    hand_eye_frames,
    run_hand_eye,
)
from .common import (
    EXIT_CALIB,
    EXIT_INPUT,
    EXIT_OK,
    error,
    image_paths_or_none,
    progress,
    session_defaults,
    target_or_none,
    write_result,
)

SessionInput = tuple[str, str, list[Detection], list[Transform | None], str, list[Path]]


def add_parser(sub: argparse._SubParsersAction) -> None:
    h = sub.add_parser("handeye", help="intrinsics + hand-eye transform from images and robot poses (POSES.yaml), "
                                       "or from a recorded arm session (rosbag2)")
    h.add_argument("--target", help="target YAML file or packaged name (default: the recorded session's)")
    h.add_argument("--poses", help="POSES.yaml: the tool pose in the base frame per image")
    h.add_argument("--bag", help="instead of --poses and images: a rosbag2 arm session (images and the tool pose "
                                 "as PoseStamped or TransformStamped); one still frame per rest of the arm is used")
    h.add_argument("--image-topic", default="", help="with --bag: the image topic (default: the only one)")
    h.add_argument("--pose-topic", default="", help="with --bag: the tool pose topic (default: the only one)")
    h.add_argument("--pose-max-age", type=float, default=0.1,
                   help="with --bag: a frame's pose is interpolated from samples at most this many seconds away")
    h.add_argument("--tool-frame", default="", help="with --bag: the tool frame of PoseStamped poses (default tool0)")
    h.add_argument("--mode", choices=("eye_in_hand", "eye_to_hand"), help="default: the recorded session's")
    h.add_argument("-o", "--output", required=True, help="camera YAML path")
    h.add_argument("--hand-eye-out", default="", help="HAND_EYE.yaml path (default: hand_eye.yaml beside -o)")
    h.add_argument("--camera-frame", default="camera_optical_frame")
    h.add_argument("--camera-name", default=None, help="default: camera (a session: its camera name)")
    h.add_argument("--method", choices=METHODS, help="default: the target's natural method")
    h.add_argument("--distortion", default=None, choices=sorted(DISTORTION_MODELS),
                   help="default: plumb_bob (a session: its model)")
    h.add_argument("--skew", action="store_true", help="estimate skew (default: zero skew)")
    h.add_argument("--gamma", type=float, default=None,
                   help="linearise with this display gamma before edges (default 1; a session: its gamma)")
    h.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    h.add_argument("--robot-sigma-mm", type=float, default=0.1, help="the arm's pose accuracy per axis (start)")
    h.add_argument("--robot-sigma-deg", type=float, default=0.01)
    h.add_argument("--fixed-robot-sigma", action="store_true", help="do not estimate the arm's accuracy")
    h.add_argument("--arm-accuracy-mm", type=float, default=0.2,
                   help="the arm's systematic position error per axis over the workspace (absolute accuracy), which "
                        "no session can measure; its share is added to sigma(X) (0: left out)")
    h.add_argument("--arm-accuracy-length", type=float, default=0.3, help="metres over which that error changes")
    h.add_argument("--report", metavar="DIR", help="write report.pdf (8 pages: the camera's 7 and the hand-eye "
                                                    "page), report.png and report.json into DIR")
    h.add_argument("images", nargs="*", help="image files or folders (with --poses), or a session folder recorded "
                                             "by the node (its frames, robot poses and settings)")
    h.set_defaults(func=run)


def from_bag(args: argparse.Namespace, target: Target, params: DetectionParams) -> SessionInput | None:
    """(base frame, tool frame, detections, robot poses, pose source, image files) of the still
    frames of an arm session bag (:mod:`..session.arm_bag`), or None after printing why not."""
    try:
        bag = read_arm_bag(args.bag, args.image_topic, args.pose_topic, args.pose_max_age, args.tool_frame)
        print(bag.summary())
        if not bag.used:
            error(f"no still frame with a robot pose in {args.bag} (the robot pose changes by more than 1e-6 m or "
                  "1e-6 rad around every frame)")
            return None
        frames = [(f.name, img) for f, img in bag.images()]  # only the used frames are decoded
    except BagError as e:
        error(str(e))
        return None
    dets = detect_images(frames, len(frames), target, params, progress())
    # no image files: the report draws no view images
    return bag.frame_id, bag.child_frame_id, dets, [f.pose for f in bag.used], Path(args.bag).name, []


def from_pose_file(args: argparse.Namespace, target: Target, params: DetectionParams) -> SessionInput | None:
    """The same from POSES.yaml and image files (matched by file name), or None after printing why not."""
    if not args.poses or not args.images:
        error("give --poses POSES.yaml and image files or folders, or --bag BAG")
        return None
    try:
        frame_id, child_id, poses = read_poses_yaml(args.poses)
    except PosesYamlError as e:
        error(str(e))
        return None
    paths = image_paths_or_none(args.images)
    if paths is None:
        return None
    if all(p.name not in poses for p in paths):
        error(f"no image has a pose in {args.poses} (images are matched by file name, e.g. {paths[0].name})")
        return None
    dets = detect_files(paths, target, params, progress())
    return frame_id, child_id, dets, [poses.get(p.name) for p in paths], Path(args.poses).name, paths


def from_session(folder: SessionFolder, target: Target, params: DetectionParams) -> SessionInput | None:
    """The same from a session folder the node recorded (:mod:`..io.session_folder`)."""
    m = folder.manifest
    if not folder.views or all(v.robot_pose is None for v in folder.views):
        error(f"{folder.path}: no recorded view has a robot pose")
        return None
    paths = [folder.path / v.image for v in folder.views]
    dets = detect_files(paths, target, params, progress())
    return (m.frame_id or "base_link", m.child_frame_id or "tool0", dets, [v.robot_pose for v in folder.views],
            "the session", paths)


def run(args: argparse.Namespace) -> int:
    """Joint intrinsic + hand-eye calibration from images and POSES.yaml, a recorded session, or an
    arm session bag."""
    folder = session_defaults(args)
    if folder is False:
        return EXIT_INPUT
    if args.mode is None and isinstance(folder, SessionFolder) and folder.manifest.hand_eye:
        args.mode = folder.manifest.hand_eye
    if args.target is None or args.mode is None:
        error("--target and --mode are required (unless the images are a recorded arm session folder)")
        return EXIT_INPUT
    target = target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    he = HandEyeOptions(args.mode, args.robot_sigma_mm, args.robot_sigma_deg, not args.fixed_robot_sigma,
                        arm_accuracy_mm=args.arm_accuracy_mm, arm_accuracy_length=args.arm_accuracy_length)
    if he.arm_accuracy_problem():  # before any work
        error(f"--arm-accuracy-mm / --arm-accuracy-length: {he.arm_accuracy_problem()}")
        return EXIT_INPUT
    if args.bag and (args.poses or args.images):
        error("give either --bag BAG or --poses POSES.yaml IMAGES..., not both")
        return EXIT_INPUT
    params = detection_params(args.distortion, args.gamma, args.max_blur)
    if isinstance(folder, SessionFolder):
        loaded = from_session(folder, target, params)
    else:
        loaded = from_bag(args, target, params) if args.bag else from_pose_file(args, target, params)
    if loaded is None:
        return EXIT_INPUT
    frame_id, child_id, dets, robot, pose_source, paths = loaded
    opts = CalibrationOptions(method=args.method or "", distortion=args.distortion, zero_skew=not args.skew)
    try:
        out = run_hand_eye(dets, robot, target, opts, he)
    except CalibrationError as e:  # HandEyeError included
        for d, r in zip(dets, robot, strict=True):
            if r is None:
                print(f"  rejected  {d.name}  no pose in {pose_source}")
            elif not d.ok:
                print(f"  rejected  {d.name}  {d.reason}")
        error(f"hand-eye calibration failed: {e}")
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    print(format_summary(out.assessment))
    print(hand_eye_summary(out.result))
    print(f"time: calibration {out.seconds:.2f} s")
    frames = hand_eye_frames(args.mode, frame_id, child_id, args.camera_frame)
    he_out = Path(args.hand_eye_out) if args.hand_eye_out else Path(args.output).parent / HAND_EYE_FILE
    write_result(lambda p, name, report: out.write(p, name, frames, report),
                 ResultPaths(Path(args.output), he_out, Path(args.report) if args.report else None),
                 args.camera_name, dets, paths)
    print("publish it with:\n  " + static_transform_command(out.result.hand_eye, frames.parent, frames.camera))
    return EXIT_OK
