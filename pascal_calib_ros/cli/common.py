"""What every command shares: exit codes, loading a target, reading image arguments, the report."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..analysis.assessment import Assessment
from ..calibrate.handeye import HandEyeResult
from ..detect.detection import Detection
from ..io.images import expand_image_args, read_grey
from ..report.pages import write_report
from ..targets import Target, TargetError, resolve_target

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


def write_report_files(a: Assessment, dets: list[Detection], out_dir: str, paths: list[Path],
                       hand_eye: HandEyeResult | None = None) -> None:
    """The report in ``out_dir`` (:mod:`..report`), the worst views drawn on their own images."""
    by_name = {p.name: p for p in paths}
    t0 = time.perf_counter()
    files = write_report(a, dets, out_dir, images=lambda n: read_grey(by_name[n]) if n in by_name else None,
                         hand_eye=hand_eye)
    print(f"wrote {files.pdf}, {files.png} and {files.json} ({time.perf_counter() - t0:.1f} s)")


def distance_arg(text: str) -> float:
    """A distance in metres (> 0) or ``inf``, for argparse."""
    try:
        d = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a distance in metres nor 'inf'") from None
    if not d > 0:
        raise argparse.ArgumentTypeError(f"the distance must be positive (or inf), not {text}")
    return d
