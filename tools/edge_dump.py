#!/usr/bin/env python3
"""Detections of a fixed set of renders, saved and compared: do two versions of the detector
find the same edges? (used to check that the compiled edge fits changed nothing beyond noise).

  dump FILE.npz      detect every shipped target on the bench frames (``pascal-calib bench``'s
                     renders, 3 views at 800x600, 1920x1080 and 2456x2058) and on 4 renders each
                     of 4 circle targets at 1024x768 with k1 = -0.43; save every edge's points
                     and conic, the corners and the rejection reasons
  compare A B        per edge the largest distance between the same edge point in A and B; an
                     edge sampled from another start angle (a near-circular ellipse whose axes
                     swapped under a rounding change: other points of the same curve) is compared
                     by the largest distance between the two fitted conics instead

Run the dump once with each version of the code (e.g. PYTHONPATH=/path/to/old/checkout for the
old one, from outside the source tree), then compare.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry.conic import Ellipse, sampson_distance
from pascal_calib_ros.targets import resolve_target


def _frames() -> dict[str, np.ndarray]:
    from pascal_calib_ros.sim.session import SessionSpec, render_session_views
    from pascal_calib_ros.studies.bench import SIZES, bench_frames, shipped_targets

    out = {}
    for name in shipped_targets():
        for w, h in SIZES:
            imgs = bench_frames(resolve_target(name), SessionSpec(width=w, height=h, views=3, seed=7))
            for k, img in enumerate(imgs):
                out[f"{name}|{w}x{h}|{k}"] = img
    for name in ("ring_a4", "ring_grid_a4", "disc_grid_a4", "pascal_board_a3"):
        spec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=4, seed=5)
        _, views = render_session_views(resolve_target(name), spec)
        for k, v in enumerate(views):
            out[f"{name}|1024x768 k1=-0.43|{k}"] = v.image
    return out


def dump(path: Path) -> None:
    out: dict[str, np.ndarray] = {}
    for key, img in _frames().items():
        det = detect_target(img, resolve_target(key.split("|")[0]))
        out[f"{key}|reason"] = np.array(det.reason)
        for e in det.edges:
            out[f"{key}|e{e.circle}"] = e.points
            out[f"{key}|c{e.circle}"] = e.conic
        if det.corners is not None:
            out[f"{key}|corners"] = det.corners
    np.savez(path, **out)
    print(f"{path}: {sum(k.endswith('|reason') for k in out)} frames, {sum('|e' in k for k in out)} edges")


def compare(a_path: Path, b_path: Path) -> int:
    A, B = np.load(a_path), np.load(b_path)
    if set(A.files) != set(B.files):
        print(f"different detections: only in {a_path}: {sorted(set(A.files) - set(B.files))[:10]}, "
              f"only in {b_path}: {sorted(set(B.files) - set(A.files))[:10]}")
    worst: dict[str, float] = {}
    diffs, resampled, conic_max, n_edges = [], [], 0.0, 0
    for k in sorted(set(A.files) & set(B.files)):
        last = k.rsplit("|", 1)[1]
        target = k.split("|")[0]
        if last == "reason":
            if str(A[k]) != str(B[k]):
                print(f"{k}: {A[k]!r} -> {B[k]!r}")
        elif last == "corners":
            d = float(np.abs(A[k] - B[k]).max()) if A[k].shape == B[k].shape else np.inf
            worst[target + " corners"] = max(worst.get(target + " corners", 0.0), d)
        elif last.startswith("e"):
            n_edges += 1
            ck = k[: -len(last)] + "c" + last[1:]
            q = Ellipse.from_conic(B[ck]).sample(720)
            cd = float(np.abs(sampson_distance(A[ck], q)).max())  # new fitted edge to the old one
            conic_max = max(conic_max, cd)
            a, b = A[k], B[k]
            if a.shape == b.shape and np.abs(a - b).max() < 0.5:
                d = np.abs(a - b).max(1)
                diffs.append(d)
                worst[target] = max(worst.get(target, 0.0), float(d.max()))
            else:
                resampled.append(f"{k} (fitted conics {cd:.1e} px apart)")
    for t, d in sorted(worst.items()):
        print(f"{t:<28} largest point difference {d:.1e} px")
    d = np.concatenate(diffs) if diffs else np.zeros(1)
    print(f"{n_edges} edges, {len(d)} points: point differences median {np.median(d):.1e}, 99 % "
          f"{np.quantile(d, 0.99):.1e}, 99.9 % {np.quantile(d, 0.999):.1e}, max {d.max():.1e} px")
    print(f"{len(resampled)} edge(s) sampled from another start angle" + (": " if resampled else "")
          + "; ".join(resampled))
    print(f"largest distance between an edge's two fitted conics: {conic_max:.1e} px")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dump")
    d.add_argument("file", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    a = ap.parse_args()
    if a.cmd == "dump":
        dump(a.file)
        return 0
    return compare(a.a, a.b)


if __name__ == "__main__":
    sys.exit(main())
