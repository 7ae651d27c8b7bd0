#!/usr/bin/env python3
"""Hand-eye on a real checkerboard arm dataset: X from one half of the views against X from the other.

Reads a folder in the layout of the CIVIT / Tampere University robot-world hand-eye datasets
(Ali, Suominen, Gotchev, Morales, "Methods for Simultaneous Robot-World-Hand-Eye Calibration: A
Comparative Study", Sensors 19(12) 2837, 2019; https://github.com/ihtishamaliktk/RWHE-Calib,
Datasets/kuka_1 .. kuka_3; open-access data, cite the paper): ``NN.png`` or ``im_NN.bmp`` (NN = 01, 02, ...),
``RobotPosesVec.txt`` (one row-major 4x4 T_base_gripper per line, metres) and ``squaresize.txt``
(e.g. ``20mm``). The camera rides on the arm (eye in hand). Nothing of the dataset is stored in
this repository.

The views are split into two halves (interleaved: even and odd view numbers, so that both halves
see the whole motion range); each half is calibrated on its own (intrinsics and X), by
:func:`calibrate_hand_eye` and by OpenCV 4.x (calibrateCamera on OpenCV's checkerboard corners,
then calibrateHandEye with its five methods, through ``tools/opencv_handeye.py`` in the Python
given by ``--opencv4-python``). The table gives, per method, the difference of the two halves'
X (translation mm, rotation deg) and, for ours, the sigma of that difference the two estimates
report (sqrt(s1^2 + s2^2), norm over the axes).

    .venv/bin/python tools/handeye_real.py DATASET_DIR --out OUT_DIR --opencv4-python /tmp/cv4/bin/python
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from pascal_calib_ros.calibrate.handeye import calibrate_hand_eye
from pascal_calib_ros.calibrate.intrinsic.result import CalibrationError
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.report.text import hand_eye_summary
from pascal_calib_ros.targets import load_target

TOOL = Path(__file__).resolve().parent / "opencv_handeye.py"


def read_dataset(folder: Path) -> tuple[list[Path], list[Transform], float]:
    poses = np.loadtxt(folder / "RobotPosesVec.txt").reshape(-1, 4, 4)
    m = re.match(r"\s*([0-9.]+)\s*(mm|cm|m)?", (folder / "squaresize.txt").read_text())
    if not m:
        raise SystemExit("squaresize.txt: expected e.g. '20mm'")
    size = float(m.group(1)) * {"mm": 1e-3, "cm": 1e-2, "m": 1.0, None: 1.0}[m.group(2)]
    # kuka_1 names its images NN.png, kuka_2 im_NN.bmp
    images = [next((q for q in (folder / f"{k + 1:02d}.png", folder / f"im_{k + 1:02d}.bmp") if q.exists()),
                   folder / f"{k + 1:02d}.png") for k in range(len(poses))]
    return images, [Transform.from_rt(P[:3, :3], P[:3, 3]) for P in poses], size


def board_target(inner: tuple[int, int], size: float, out: Path):
    """A target YAML for a checkerboard of ``inner`` (x, y) inner corners."""
    nx, ny = inner[0] + 1, inner[1] + 1
    text = (f"name: real_checkerboard\nsheet: {{width: {nx * size + 0.02:.4f}, height: {ny * size + 0.02:.4f}}}\n"
            "features:\n  - type: checkerboard\n    origin: [0.01, 0.01]\n"
            f"    squares: [{nx}, {ny}]\n    square_size: {size}\n    first_square: black\n")
    p = out / "real_checkerboard.yaml"
    p.write_text(text)
    return load_target(p)


def opencv_half(corners: list[np.ndarray], obj: np.ndarray, size: tuple[int, int], poses: list[Transform],
                out: Path, tag: str, py: str) -> dict[str, Transform]:
    objs = [np.c_[obj, np.zeros(len(obj))].astype(np.float32)] * len(corners)
    pts = [c.reshape(-1, 1, 2).astype(np.float32) for c in corners]
    _, _K, _D, rvecs, tvecs = cv2.calibrateCamera(objs, pts, size, None, None)
    views = [{"R_base_tool": G.R.tolist(), "t_base_tool": G.translation.tolist(),
              "R_cam_target": cv2.Rodrigues(rv)[0].tolist(), "t_cam_target": np.ravel(tv).tolist()}
             for G, rv, tv in zip(poses, rvecs, tvecs, strict=True)]
    inp, res = out / f"opencv_in_{tag}.json", out / f"opencv_out_{tag}.json"
    inp.write_text(json.dumps({"mode": "eye_in_hand", "views": views}))
    r = subprocess.run([py, str(TOOL), str(inp), str(res)], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    doc = json.loads(res.read_text())
    return {f"opencv {doc['opencv']} {k}": Transform.from_rt(np.array(v["R"]), v["t"])
            for k, v in doc["methods"].items() if "error" not in v}


def diff(a: Transform, b: Transform) -> tuple[float, float]:
    return (float(1000 * np.linalg.norm(a.translation - b.translation)),
            float(np.degrees(np.linalg.norm((a.rotation * b.rotation.inv()).as_rotvec()))))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--out", type=Path, default=Path("handeye_real"))
    ap.add_argument("--inner", type=int, nargs=2, default=(28, 17), metavar=("NX", "NY"),
                    help="inner corners along x and y (kuka_1: 28 17, kuka_2: 24 17)")
    ap.add_argument("--opencv4-python", default="")
    ap.add_argument("--max-views", type=int, default=0, help="use only the first N views (0: all)")
    ap.add_argument("--splits", type=int, default=1, help="also the median over this many splits into halves "
                                                            "(even/odd, then seeded random halves)")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    images, poses, size = read_dataset(a.folder)
    if a.max_views:
        images, poses = images[:a.max_views], poses[:a.max_views]
    target = board_target(tuple(a.inner), size, Path(tempfile.mkdtemp()))
    board = target.checkerboard
    assert board is not None
    dets, ims = [], []
    for p in images:
        im = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        ims.append(im)
        dets.append(detect_target(im, target, name=p.name))
    ok = [k for k, d in enumerate(dets) if d.corners is not None]
    print(f"{len(ok)}/{len(dets)} views with the board ({time.perf_counter() - t_start:.0f} s)", flush=True)
    h, w = ims[0].shape[:2]

    def split_result(halves: dict[str, list[int]], tag: str, verbose: bool
                     ) -> tuple[dict[str, dict[str, Transform]], dict[str, tuple[np.ndarray, np.ndarray]]]:
        res: dict[str, dict[str, Transform]] = {}
        sig: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for half, sel in halves.items():
            res[half] = {}
            try:
                r = calibrate_hand_eye([dets[k] for k in sel], [poses[k] for k in sel], target, "eye_in_hand")
                res[half]["ours"] = r.hand_eye
                sig[half] = (r.translation_std_mm, r.rotation_std_deg)
                if verbose:
                    print(f"--- half {half} ({len(sel)} views)\n{hand_eye_summary(r)}", flush=True)
            except CalibrationError as e:
                print(f"half {half}: ours failed: {e}")
            if a.opencv4_python:
                corners = [np.asarray(dets[k].corners, float) for k in sel]
                res[half].update(opencv_half(corners, board.corner_points(), (w, h), [poses[k] for k in sel], a.out,
                                             f"{tag}_{half}", a.opencv4_python))
        return res, sig

    halves = {"even": [k for k in ok if k % 2 == 0], "odd": [k for k in ok if k % 2 == 1]}
    res, sig = split_result(halves, "evenodd", True)
    lines = [f"real data {a.folder.name}: {len(ok)} views, halves even/odd ({len(halves['even'])}, "
             f"{len(halves['odd'])} views), eye in hand; difference of the halves' X",
             f"{'method':<30} {'d mm':>8} {'d deg':>8} {'sig mm':>8} {'sig deg':>8}"]
    rows = []
    for name in res["even"]:
        if name not in res["odd"]:
            continue
        dmm, ddeg = diff(res["even"][name], res["odd"][name])
        row = {"method": name, "diff_mm": dmm, "diff_deg": ddeg}
        s = ""
        if name == "ours" and "even" in sig and "odd" in sig:
            st = np.hypot(sig["even"][0], sig["odd"][0])
            sr = np.hypot(sig["even"][1], sig["odd"][1])
            row["sigma_mm"], row["sigma_deg"] = float(np.linalg.norm(st)), float(np.linalg.norm(sr))
            s = f" {row['sigma_mm']:8.3f} {row['sigma_deg']:8.4f}"
        rows.append(row)
        lines.append(f"{name:<30} {dmm:8.3f} {ddeg:8.4f}{s}")
    if a.splits > 1:
        # more splits: random halves (seeded), the same for every method; median difference per method
        rng = np.random.default_rng(0)
        per: dict[str, list[tuple[float, float]]] = {}
        for j in range(a.splits):
            if j == 0:
                rj = res
            else:
                perm = rng.permutation(ok)
                half = len(perm) // 2
                rj, _ = split_result({"a": sorted(perm[:half]), "b": sorted(perm[half:])}, f"split{j}", False)
            ka, kb = list(rj)
            for name in rj[ka]:
                if name in rj[kb]:
                    per.setdefault(name, []).append(diff(rj[ka][name], rj[kb][name]))
        lines.append(f"over {a.splits} splits (even/odd and {a.splits - 1} random halves): median [min-max] of the "
                     "halves' difference")
        for name, v in per.items():
            d = np.array(v)
            lines.append(f"{name:<30} {np.median(d[:, 0]):8.3f} mm [{d[:, 0].min():.3f}-{d[:, 0].max():.3f}]  "
                         f"{np.median(d[:, 1]):8.4f} deg [{d[:, 1].min():.4f}-{d[:, 1].max():.4f}]")
            rows.append({"method": name, "splits": len(v), "median_diff_mm": float(np.median(d[:, 0])),
                         "median_diff_deg": float(np.median(d[:, 1]))})
    lines.append(f"run time {time.perf_counter() - t_start:.0f} s")
    text = "\n".join(lines)
    print(text)
    (a.out / "handeye_real.txt").write_text(text + "\n")
    (a.out / "handeye_real.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
