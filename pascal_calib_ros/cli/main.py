"""``pascal-calib``: offline calibration, synthetic sessions, studies and benchmarks.

Exit codes: 0 success, 1 calibration not possible (too few views, degenerate set), 2 bad input
(arguments, target file, images).
"""

from __future__ import annotations

import argparse
import sys

from . import bag, calibrate, diff, export, handeye, render, stereo, studies, suggest, target, verify
from .common import EXIT_INPUT, error

# each command module: add_parser(sub), and the function it sets as the parser's func
COMMANDS = (calibrate, suggest, handeye, stereo, diff, export, verify, render, bag, studies, target)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="pascal-calib", description=__doc__.splitlines()[0] if __doc__ else None)
    sub = ap.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if getattr(args, "min_views", 3) < 3:
        error("--min-views must be at least 3")
        return EXIT_INPUT
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
