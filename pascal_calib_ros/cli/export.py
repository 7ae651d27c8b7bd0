"""``pascal-calib export``: a calibration in another tool's format (the work: :mod:`..workflows.export`).

Exit codes: 0 written, 1 a refit refused (its error above ``--max-error``; ``--force`` writes it),
2 bad input (unreadable file, a model the format cannot hold, bad arguments).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..analysis import DEFAULT_MAX_ERROR_PX, RefitError
from ..errors import PascalCalibError
from ..geometry import DISTORTION_CHOICES
from ..workflows import FORMATS, ExportRequest, export_calibration
from .common import EXIT_CALIB, EXIT_INPUT, EXIT_OK, error


def add_parser(sub: argparse._SubParsersAction) -> None:
    x = sub.add_parser("export", help="a calibration in OpenCV, Kalibr, mrcal or JSON format (refitted where the "
                                      "format lacks the model, with the error stated); a HAND_EYE.yaml as a URDF "
                                      "joint or a static_transform_publisher command")
    x.add_argument("calibration", metavar="CAL", help="calibration file (ROS YAML, calibration.json, OpenCV, Kalibr, "
                                                      "mrcal) or, with --to urdf|static_transform, a HAND_EYE.yaml")
    x.add_argument("--to", required=True, choices=FORMATS)
    x.add_argument("-o", "--output", required=True, help="output file")
    x.add_argument("--model", choices=sorted(DISTORTION_CHOICES),
                   help="refit into this lens model (plumb_bob; none = a pinhole; Kalibr: plumb_bob means radtan, "
                        "k3 = 0); default: only where the format needs it")
    x.add_argument("--region", metavar="REPORT_JSON",
                   help="fit the refit over the observed field of a report.json or calibration.json "
                        "(coverage.view_hulls; default: the whole image)")
    x.add_argument("--max-error", type=float, default=DEFAULT_MAX_ERROR_PX, metavar="PX",
                   help="refuse a refit whose worst projection error over the region exceeds this")
    x.add_argument("--force", action="store_true", help="write a refit above --max-error anyway")
    x.add_argument("--camera", default="", help="the entry of a multi-camera file (Kalibr: cam0, cam1, ...)")
    x.add_argument("--rostopic", default="", help="--to kalibr: the camera's image topic")
    x.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    req = ExportRequest(source=Path(args.calibration), to=args.to, output=Path(args.output), model=args.model or "",
                        region=Path(args.region) if args.region else None, force=args.force,
                        max_error_px=args.max_error, camera=args.camera, rostopic=args.rostopic)
    try:
        out = export_calibration(req)
    except RefitError as e:
        error(str(e))
        print("nothing written", file=sys.stderr)
        return EXIT_CALIB
    except (PascalCalibError, OSError) as e:
        error(str(e))
        return EXIT_INPUT
    print("\n".join(out.lines))
    return EXIT_OK
