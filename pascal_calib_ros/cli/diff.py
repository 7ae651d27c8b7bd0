"""``pascal-calib diff``: how much two calibrations of one camera differ, in pixels (mrcal's
projection_diff, :mod:`..analysis.compare`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..analysis import projection_difference, region_from_report
from ..errors import PascalCalibError
from ..io import read_calibration_file
from .common import EXIT_INPUT, EXIT_OK, error


def add_parser(sub: argparse._SubParsersAction) -> None:
    df = sub.add_parser("diff", help="projection difference between two calibrations of one camera (after the "
                                     "implied rotation, as mrcal-show-projection-diff)")
    df.add_argument("a", metavar="A.yaml", help="the reference calibration: ROS camera YAML, calibration.json, "
                                                "OpenCV FileStorage, Kalibr camchain (cam0) or mrcal .cameramodel")
    df.add_argument("b", metavar="B.yaml", help="the calibration compared against A (any of those formats)")
    df.add_argument("--region", default="image", metavar="image|REPORT_JSON",
                    help="grid over the whole image (default) or over the observed field of a calibration "
                         "report.json (coverage.view_hulls)")
    df.add_argument("--distance", type=float, default=None, metavar="M",
                    help="range of the compared points in metres (default: infinity, rotation-only fit; "
                         "finite: rotation and translation are fitted)")
    df.add_argument("--step", type=float, default=16.0, metavar="PX", help="grid spacing in pixels")
    df.add_argument("--plot", metavar="OUT.png", help="write a heat map of the difference over the image")
    df.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Projection difference of calibration B against A after the implied rotation (mrcal's
    projection_diff; :mod:`.calibrate.compare`), over the image or a report's observed field."""
    try:
        a, b = read_calibration_file(args.a).camera, read_calibration_file(args.b).camera
        mask = None if args.region == "image" else region_from_report(args.region).mask
        res = projection_difference(a, b, mask, args.distance, args.step)
    except PascalCalibError as e:
        error(str(e))
        return EXIT_INPUT
    print(res.summary())
    if res.n_excluded:
        print(f"note: {res.n_excluded} grid point(s) left out (beyond the range of one of the models)", file=sys.stderr)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        img, extent = res.image()
        fig, ax = plt.subplots(figsize=(8.0, 6.0 * a.height / a.width + 1.2))
        im = ax.imshow(img, extent=extent, origin="upper", interpolation="nearest", cmap="viridis")
        if mask is not None:
            ax.contour(mask.astype(np.uint8), levels=[0.5], colors="red", linewidths=1.0)
        ax.set_xlim(0, a.width)
        ax.set_ylim(a.height, 0)
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
        rng = "infinity" if args.distance is None else f"{args.distance:g} m"
        where = "image" if mask is None else f"{Path(args.region).name} (red outline)"
        ax.set_title(f"{Path(args.b).name} against {Path(args.a).name}, range {rng}, region {where}\n"
                     f"{res.summary()}", fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.9, label="projection difference (px)")
        fig.tight_layout()
        try:
            Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(args.plot, dpi=100)
        except (OSError, ValueError) as e:  # unwritable path, unknown image format
            print(f"error: cannot write {args.plot}: {e}", file=sys.stderr)
            return EXIT_INPUT
        finally:
            plt.close(fig)
        print(f"wrote {args.plot}")
    return EXIT_OK
