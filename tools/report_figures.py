"""The README's report figures: one PNG per page of ``report.pdf`` and the one-page summary.

A rendered session (`ring_grid_a4`, 12 views, 1024x768, a 115-degree wide-angle lens whose true
model is rational_polynomial) calibrated with plumb_bob, which cannot describe it: the report
shows the residual pattern, calls the model bias and names what to try. The same views
calibrated with rational_polynomial are reported beside it for the verdict's other side.

``.venv/bin/python tools/report_figures.py [--out docs/figures]`` (about a minute).
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

from pascal_calib_ros.analysis.statistics.assessment import assess
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.report.pages import write_report
from pascal_calib_ros.sim.session import render_session_views
from pascal_calib_ros.studies.model_bias_study import cases
from pascal_calib_ros.targets import resolve_target


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/figures")
    args = ap.parse_args()
    case = next(c for c in cases() if c.label.startswith("rational"))
    target = resolve_target(case.target)
    _, views = render_session_views(target, case.spec)
    dets = [detect_target(v.image, target, name=f"view_{k:02d}.png") for k, v in enumerate(views)]
    images = {d.name: v.image for d, v in zip(dets, views, strict=True)}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for distortion in ("plumb_bob", "rational_polynomial"):
        res = calibrate(dets, target, CalibrationOptions(distortion=distortion))
        with tempfile.TemporaryDirectory() as tmp:
            files = write_report(assess(res), dets, tmp, images=images.get, page_images=distortion == "plumb_bob")
            bias = json.loads(files.json.read_text())["residuals"]["model_bias"]
            print(f"{distortion}: rms {res.rms:.4f} px, model bias detected {bias['detected']}, largest regional "
                  f"mean {bias['max_regional_px']:.4f} px, radial {bias['radial_px']}")
            if distortion == "plumb_bob":
                for page in sorted(Path(tmp).glob("report_page_*.png")):
                    shutil.copy(page, out / page.name)
                shutil.copy(files.png, out / "report_example.png")
    print(f"wrote {out}/report_page_1.png ... and {out}/report_example.png")


if __name__ == "__main__":
    main()
