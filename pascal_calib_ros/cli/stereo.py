"""``pascal-calib stereo`` and ``pascal-calib rig``: a stereo pair or a camera rig in one estimate
(the work: :mod:`..workflows.stereo`); ``pascal-calib stereo SESSION``: a stereo session recorded
by the node, with the settings it was recorded with (:func:`~..workflows.stereo_session.
run_recorded_stereo`)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..calibrate import DISTORTION_MODELS, METHODS, CalibrationOptions, RigOptions
from ..detect import DetectionParams
from ..errors import PascalCalibError
from ..io import SessionFolder, SessionFolderError
from ..workflows import (
    PairingError,
    StereoOptions,
    detection_params,
    run_recorded_stereo,
    run_rig,
    run_stereo,
    write_reports,
)
from .common import EXIT_CALIB, EXIT_INPUT, EXIT_OK, error, progress, target_or_none


def add_parser(sub: argparse._SubParsersAction) -> None:
    st = sub.add_parser("stereo", help="stereo pair: both cameras' intrinsics and their transform in one "
                                       "estimate; writes left.yaml, right.yaml (as camera_calibration) and stereo.yaml")
    _rig_arguments(st, stereo=True)
    st.add_argument("session", nargs="?", metavar="SESSION",
                    help="instead of --left and --right: a stereo session folder recorded by the node (its shots "
                         "and settings; docs/stereo-and-rigs.md)")
    st.add_argument("--left", nargs="+", metavar="GLOB", help="left images: folder, files or glob")
    st.add_argument("--right", nargs="+", metavar="GLOB", help="right images: folder, files or glob")
    st.add_argument("--alpha", type=float, default=0.0,
                    help="rectification: 0 valid pixels only (camera_calibration's default) .. 1 every source pixel")
    st.add_argument("--camera-name", default=None, help="left.yaml / right.yaml hold NAME/left, NAME/right "
                                                        "(default narrow_stereo; a session: its camera name)")
    st.add_argument("--left-frame", default=None, help="default left_camera_optical_frame (a session: its own)")
    st.add_argument("--right-frame", default=None, help="default right_camera_optical_frame (a session: its own)")
    st.set_defaults(func=run_stereo_command)

    rg = sub.add_parser("rig", help="camera rig: every camera's intrinsics and pose in the first camera's frame in "
                                    "one estimate; writes NAME.yaml per camera and rig.yaml")
    _rig_arguments(rg)
    rg.add_argument("--camera", action="append", required=True, metavar="NAME=GLOB",
                    help="a camera and its images (folder or quoted glob); give it once per camera, the first is "
                         "the reference; shots are matched by file stem")
    rg.set_defaults(func=run_rig_command)



def _rig_options(args: argparse.Namespace) -> tuple[Any, DetectionParams]:
    params = detection_params(args.distortion, args.gamma, args.max_blur)
    opts = CalibrationOptions(method=args.method or "", distortion=args.distortion, zero_skew=not args.skew,
                              min_views=args.min_views)
    return RigOptions(calibration=opts), params


STEREO_DEFAULTS: dict[str, Any] = {
    "target": None, "distortion": "plumb_bob", "gamma": 1.0, "camera_name": "narrow_stereo",
    "left_frame": "left_camera_optical_frame", "right_frame": "right_camera_optical_frame"}


def stereo_inputs(args: argparse.Namespace) -> SessionFolder | bool | None:
    """The recorded session given as SESSION (its settings fill the options left unset, an option
    given wins and is noted), None for ``--left`` and ``--right`` (the defaults fill the options),
    or False after printing why the inputs cannot be used."""
    if args.session is None:
        if not (args.left and args.right):
            error("give --left and --right, or a stereo session folder recorded by the node")
            return False
        for k, v in STEREO_DEFAULTS.items():
            if getattr(args, k) is None:
                setattr(args, k, v)
        return None
    if args.left or args.right:
        error("give a recorded session or --left and --right, not both")
        return False
    try:
        folder = SessionFolder.open(args.session)
    except SessionFolderError as e:
        error(str(e))
        return False
    m = folder.manifest
    if m.cameras != ("left", "right"):
        error(f"{folder.path} is not a stereo session (one camera): use pascal-calib calibrate")
        return False
    recorded = {"target": folder.target_source(), "distortion": m.distortion_model, "gamma": m.gamma,
                "camera_name": m.camera_name, "left_frame": m.frame_id, "right_frame": m.child_frame_id}
    for k, v in recorded.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
        elif getattr(args, k) != v:
            print(f"note: --{k.replace('_', '-')} {getattr(args, k)} (the session was recorded with {v})")
    print(f"session {folder.path}: {len(folder.views)} shot(s), target {m.target}, {m.distortion_model}, "
          f"gamma {m.gamma:g}")
    return folder


def run_stereo_command(args: argparse.Namespace) -> int:
    """A stereo pair (workflows/stereo.py): left.yaml, right.yaml, stereo.yaml; from image files or
    from a recorded session."""
    folder = stereo_inputs(args)
    if folder is False:
        return EXIT_INPUT
    if args.target is None:
        error("--target is required (unless the input is a recorded session folder)")
        return EXIT_INPUT
    target = target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    rig_opts, params = _rig_options(args)
    opts = StereoOptions(rig_opts, args.alpha, args.camera_name, args.left_frame, args.right_frame)
    try:
        if isinstance(folder, SessionFolder):
            pairing, dets, outcome = run_recorded_stereo(folder, target, opts, params, args.output)
        else:
            pairing, dets, outcome = run_stereo(args.left, args.right, target, args.output, opts, params,
                                                progress=progress())
    except PairingError as e:
        error(str(e))
        return EXIT_INPUT
    except PascalCalibError as e:
        error(f"stereo calibration failed: {e}")
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    print(f"shots paired {pairing.how}: {len(pairing.shots)} shots" +
          (f"; without a partner: {', '.join(pairing.unmatched)}" if pairing.unmatched else ""))
    print("\n".join(outcome.lines))
    if args.report:
        files = write_reports(outcome.rig, dets, pairing, args.report, outcome, target)
        print("wrote " + ", ".join(str(f) for f in files))
    return EXIT_OK


def run_rig_command(args: argparse.Namespace) -> int:
    """N cameras (workflows/stereo.py): one camera YAML per camera and rig.yaml."""
    target = target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    rig_opts, params = _rig_options(args)
    try:
        pairing, dets, outcome = run_rig(args.camera, target, args.output, rig_opts, params,
                                         progress=progress())
    except PairingError as e:
        error(str(e))
        return EXIT_INPUT
    except PascalCalibError as e:
        error(f"rig calibration failed: {e}")
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    print(f"shots matched {pairing.how}: {len(pairing.shots)} shots" +
          (f"; seen by one camera only: {', '.join(pairing.unmatched)}" if pairing.unmatched else ""))
    print("\n".join(outcome.lines))
    if args.report:
        files = write_reports(outcome.rig, dets, pairing, args.report)
        print("wrote " + ", ".join(str(f) for f in files))
    return EXIT_OK


def _rig_arguments(p: argparse.ArgumentParser, stereo: bool = False) -> None:
    """The options `stereo` and `rig` share (stereo: a recorded session's settings fill the unset ones)."""
    session = " (a session: its own)" if stereo else ""
    p.add_argument("--target", required=not stereo, help="target YAML file or packaged name (ring_grid_a4, ...)"
                                                         + session)
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--method", choices=METHODS, help="default: the target's natural method")
    p.add_argument("--distortion", default=None if stereo else "plumb_bob", choices=sorted(DISTORTION_MODELS),
                   help="default plumb_bob" + session)
    p.add_argument("--skew", action="store_true", help="estimate skew (default: zero skew)")
    p.add_argument("--gamma", type=float, default=None if stereo else 1.0,
                   help="linearise with this display gamma before edges (default 1)" + session)
    p.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    p.add_argument("--min-views", type=int, default=3, help="per camera")
    p.add_argument("--report", metavar="DIR", help="write each camera's report into DIR/<camera>/ (stereo: and the "
                                                   "pair's page DIR/stereo.pdf)")
