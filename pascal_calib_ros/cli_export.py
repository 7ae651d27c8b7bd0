"""``pascal-calib export``: arguments and exit codes (the work: :mod:`.workflows.export`).

Exit codes: 0 written, 1 a refit refused (its error above ``--max-error``; ``--force`` writes it),
2 bad input (unreadable file, a model the format cannot hold, bad arguments).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_OK, EXIT_REFUSED, EXIT_INPUT = 0, 1, 2


def cmd_export(args: argparse.Namespace) -> int:
    from .analysis.refit import RefitError
    from .errors import PascalCalibError
    from .workflows.export import ExportRequest, export_calibration

    req = ExportRequest(source=Path(args.calibration), to=args.to, output=Path(args.output), model=args.model or "",
                        region=Path(args.region) if args.region else None, force=args.force,
                        max_error_px=args.max_error, camera=args.camera, rostopic=args.rostopic)
    try:
        out = export_calibration(req)
    except RefitError as e:
        print(f"error: {e}", file=sys.stderr)
        print("nothing written", file=sys.stderr)
        return EXIT_REFUSED
    except (PascalCalibError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_INPUT
    print("\n".join(out.lines))
    return EXIT_OK


def add_export_parser(sub: argparse._SubParsersAction) -> None:
    from .analysis.refit import DEFAULT_MAX_ERROR_PX
    from .geometry.lens import DISTORTION_CHOICES
    from .workflows.export import FORMATS

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
    x.set_defaults(func=cmd_export)


def write_sidecar(res: object, camera_yaml: str | Path, camera_name: str) -> Path:
    """``CAM.calibration.json`` beside the camera YAML (:mod:`.io.calibration_json`: the covariance
    ``pascal-calib verify`` tests against and the observed field ``export --region`` refits over);
    ``res``: a :class:`~.calibrate.pipeline.CalibrationResult`."""
    from .io.calibration_json import sidecar_path, write_calibration_json
    from .workflows.calibration_record import record_of_calibration

    return write_calibration_json(sidecar_path(camera_yaml), record_of_calibration(res, camera_name))  # type: ignore[arg-type]
