"""``make demo``: render a sample session of the ring target, calibrate it with the command-line
tool exactly as a user would, and compare the result with the renderer's ground truth."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .cli import main as cli_main
from .geometry.camera import Camera, model_error
from .io.camera_yaml import read_camera_yaml
from .sim.session import SessionSpec, render_session
from .targets import resolve_target

OUT = Path("demo_out")


def compare(truth_json: Path, calib_yaml: Path) -> dict[str, float]:
    truth = json.loads(truth_json.read_text())
    info = read_camera_yaml(calib_yaml)
    cam_t = Camera(np.array(truth["K"]), np.array(truth["D"]), truth["width"], truth["height"])
    cam_e = Camera(info.K, info.D, info.width, info.height)
    return {
        "fx_err_pct": 100 * (info.K[0, 0] / cam_t.K[0, 0] - 1),
        "fy_err_pct": 100 * (info.K[1, 1] / cam_t.K[1, 1] - 1),
        "cx_err_px": info.K[0, 2] - cam_t.K[0, 2],
        "cy_err_px": info.K[1, 2] - cam_t.K[1, 2],
        "model_err_px": model_error(cam_t, cam_e, cam_t.width, cam_t.height),
    }


def main() -> int:
    session = OUT / "session"
    spec = SessionSpec(width=800, height=600, k1=-0.25, views=12, blur=1.0, gamma=2.2, noise=1.5, seed=3,
                       cut_views=1, empty_views=1, defocused_views=1)
    if not (session / "session.json").exists():
        print(f"rendering a sample session into {session}/ (12 good views + 3 that must be rejected)")
        render_session(resolve_target("ring_a4"), spec, session)
    out_yaml = OUT / "camera.yaml"
    images = sorted(str(p) for p in session.glob("*.png"))
    print("$ pascal-calib calibrate --target ring_a4 --camera-name demo_camera -o demo_out/camera.yaml "
          "demo_out/session/*.png\n")
    code = cli_main(["calibrate", "--target", "ring_a4", "--camera-name", "demo_camera", "-o", str(out_yaml),
                     *images])
    if code != 0:
        print("demo: calibration failed", file=sys.stderr)
        return code
    print("\n" + out_yaml.read_text())
    err = compare(session / "session.json", out_yaml)
    print("error against the renderer's ground truth:")
    print(f"  fx {err['fx_err_pct']:+.4f} %   fy {err['fy_err_pct']:+.4f} %   "
          f"principal point ({err['cx_err_px']:+.2f}, {err['cy_err_px']:+.2f}) px   "
          f"model error {err['model_err_px']:.3f} px RMS over the image")
    pp = float(np.hypot(err["cx_err_px"], err["cy_err_px"]))
    ok = abs(err["fx_err_pct"]) < 0.1 and abs(err["fy_err_pct"]) < 0.1 and pp < 1
    print("demo: OK" if ok else "demo: accuracy outside the documented bounds")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
