"""``pascal-calib target``: a printable target at exact scale (:mod:`..io.printable`)."""

from __future__ import annotations

import argparse

from ..io import write_printable
from ..targets import TargetError, resolve_target
from .common import EXIT_INPUT, EXIT_OK, error


def add_parser(sub: argparse._SubParsersAction) -> None:
    t = sub.add_parser("target", help="printable target at exact scale (.pdf, .svg, .png)")
    t.add_argument("--target", required=True)
    t.add_argument("-o", "--output", required=True)
    t.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        target = resolve_target(args.target)
        out = write_printable(target, args.output)
    except (TargetError, ValueError) as e:
        error(str(e))
        return EXIT_INPUT
    print(f"wrote {out} ({1000 * target.sheet[0]:g} x {1000 * target.sheet[1]:g} mm; print at 100 %)")
    return EXIT_OK
