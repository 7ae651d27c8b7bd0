"""``pascal-calib verify``: does a calibration still hold on fresh views (the work:
:mod:`..workflows.verify`)?

Exit codes: 0 the calibration holds, 3 it has changed, 1 the views cannot test it (too few usable
views, the intrinsics not determined), 2 bad input (files, arguments).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..analysis import DEFAULT_ALPHA, VerifyError
from ..errors import PascalCalibError
from ..io import expand_image_args
from ..workflows import VerifyRequest, run_verify
from .common import EXIT_CALIB, EXIT_INPUT, EXIT_OK, error

EXIT_CHANGED = 3


def add_parser(sub: argparse._SubParsersAction) -> None:
    v = sub.add_parser("verify", help="does a calibration (and a hand-eye result) still hold? Fresh views tested "
                                      "against its uncertainty; exit 0 holds, 3 changed")
    v.add_argument("--target", required=True, help="target YAML file or packaged name")
    v.add_argument("--calibration", required=True, metavar="CAL",
                   help="the calibration under test: CAM.yaml (with CAM.calibration.json beside it for its "
                        "covariance), a calibration.json, or an OpenCV / Kalibr / mrcal file (no covariance)")
    v.add_argument("--hand-eye", metavar="HAND_EYE.yaml", help="also test this hand-eye result (needs --poses)")
    v.add_argument("--poses", metavar="POSES.yaml", help="the robot pose of each image (matched by file name)")
    v.add_argument("--json", metavar="OUT", help="write every number (verdict, projection_shift_px, per-parameter z, "
                                                 "hand-eye disagreement) as JSON")
    v.add_argument("--alpha", type=float, default=DEFAULT_ALPHA,
                   help="the chance of a false 'changed' the test allows (split over the parameter groups)")
    v.add_argument("--camera", default="", help="the entry of a multi-camera calibration file (Kalibr: cam1, ...)")
    v.add_argument("--gamma", type=float, default=1.0, help="linearise with this display gamma before edges")
    v.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    v.add_argument("images", nargs="+", help="fresh image files or folders")
    v.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        req = VerifyRequest(target=args.target, calibration=Path(args.calibration),
                            images=expand_image_args(args.images),
                            hand_eye=Path(args.hand_eye) if args.hand_eye else None,
                            poses=Path(args.poses) if args.poses else None,
                            json_out=Path(args.json) if args.json else None, alpha=args.alpha, camera=args.camera,
                            gamma=args.gamma, max_blur=args.max_blur)
        out = run_verify(req)
    except VerifyError as e:
        print(f"error: the views cannot test the calibration: {e}", file=sys.stderr)
        return EXIT_CALIB
    except (PascalCalibError, OSError) as e:
        error(str(e))
        return EXIT_INPUT
    print("\n".join(out.lines))
    return EXIT_CHANGED if out.verification.verdict == "changed" else EXIT_OK
