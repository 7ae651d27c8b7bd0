"""What every command shares: exit codes, loading a target, reading image arguments, the report."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..detect import Detection
from ..io import SessionFolder, SessionFolderError, expand_image_args, is_session_folder, read_grey
from ..targets import Target, TargetError, resolve_target
from ..workflows import ReportRequest, ResultPaths, ResultWriter

EXIT_OK, EXIT_CALIB, EXIT_INPUT = 0, 1, 2


def error(message: str) -> None:
    """``error: <message>`` on stderr."""
    print(f"error: {message}", file=sys.stderr)


def target_or_none(name: str) -> Target | None:
    """The target, or None after printing why it cannot be loaded."""
    try:
        return resolve_target(name)
    except TargetError as e:
        error(str(e))
        return None


def image_paths_or_none(args: list[str]) -> list[Path] | None:
    """The image files of file and folder arguments, or None after saying there are none."""
    paths = expand_image_args(args)
    if not paths:
        error("no images given")
        return None
    return paths


def progress() -> bool:
    """Write progress lines (stderr is a terminal)."""
    return sys.stderr.isatty()


def write_result(write: ResultWriter, paths: ResultPaths, camera_name: str, dets: list[Detection],
                 images: list[Path]) -> None:
    """One result's files through the outcome's ``write`` (the node writes the same set,
    :mod:`..workflows.outputs`), each named; the report's worst views drawn on their own images."""
    by_name = {p.name: p for p in images}
    report = None if paths.report_dir is None else \
        ReportRequest(dets, lambda n: read_grey(by_name[n]) if n in by_name else None)
    t0 = time.perf_counter()
    written = write(paths, camera_name, report)
    for p in written.paths:
        print(f"wrote {p}")
    if paths.report_dir is not None:
        print(f"({time.perf_counter() - t0:.1f} s)")
    for w in written.warnings:
        print(f"WARNING: {w}", file=sys.stderr)


def distance_arg(text: str) -> float:
    """A distance in metres (> 0) or ``inf``, for argparse."""
    try:
        d = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a distance in metres nor 'inf'") from None
    if not d > 0:
        raise argparse.ArgumentTypeError(f"the distance must be positive (or inf), not {text}")
    return d


SESSION_DEFAULTS = {"distortion": "plumb_bob", "gamma": 1.0, "camera_name": "camera"}


def session_defaults(args: argparse.Namespace) -> SessionFolder | bool | None:
    """A recorded session given as the only image argument (:mod:`..io.session_folder`): its frames
    become the images, and the target, lens model, gamma and camera name it was recorded with fill
    the options left unset (``None``). Returns the folder, None when the argument is not one, or
    False after printing why it cannot be read."""
    images = list(getattr(args, "images", []) or [])
    if len(images) != 1 or not is_session_folder(images[0]):
        for k, v in SESSION_DEFAULTS.items():
            if getattr(args, k, v) is None:
                setattr(args, k, v)
        return None
    try:
        folder = SessionFolder.open(images[0])
    except SessionFolderError as e:
        error(str(e))
        return False
    m = folder.manifest
    if m.cameras:  # a shot of several cameras: the pair's own command calibrates it
        error(f"{folder.path}: a session of {len(m.cameras)} cameras ({', '.join(m.cameras)}); calibrate it with "
              f"pascal-calib stereo {folder.path}")
        return False
    recorded = {"target": folder.target_source(), "distortion": m.distortion_model, "gamma": m.gamma,
                "camera_name": m.camera_name}
    for k, v in recorded.items():
        if getattr(args, k, None) is None:
            setattr(args, k, v)
        elif getattr(args, k) != v:
            print(f"note: --{k.replace('_', '-')} {getattr(args, k)} (the session was recorded with {v})")
    args.images = [str(folder.path / v.image) for v in folder.views]
    print(f"session {folder.path}: {len(folder.views)} view(s), target {m.target}, {m.distortion_model}, "
          f"gamma {m.gamma:g}" + (f", {m.hand_eye} ({m.frame_id} -> {m.child_frame_id})" if m.hand_eye else ""))
    return folder
