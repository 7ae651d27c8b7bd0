"""Does the report's model-bias verdict (:mod:`..calibrate.residual_stats`) hold?

Two kinds of rendered sessions: lenses the chosen model describes exactly (every shipped target,
several seeds: the verdict must stay silent), and lenses it cannot (a wide-angle rational lens and
a fisheye calibrated with ``plumb_bob``: it must speak). ``pascal-calib study model-bias``.
"""

from __future__ import annotations

import csv
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import model_bias, radial, regional, residual_samples_of
from ..calibrate import CalibrationError, CalibrationOptions, calibrate
from ..detect import detect_target
from ..sim import SessionSpec, render_view, session_views
from ..targets import resolve_target
from .study import lens_cases, markdown_table

TARGETS = ("ring_a4", "ring_grid_a4", "disc_grid_a4", "pascal_board_a3", "checkerboard_a4")


@dataclass(frozen=True)
class BiasCase:
    label: str
    target: str
    spec: SessionSpec
    distortion: str
    biased: bool  # whether the model cannot describe the lens


def cases(views: int = 12, seeds: int = 4) -> list[BiasCase]:
    """``seeds`` sessions of every shipped target with a plumb_bob lens (k1 -0.2) calibrated with
    plumb_bob, and three sessions each of a 115-degree rational lens and a 120-degree fisheye
    (equidistant, f 420 px at 1024x768) calibrated with plumb_bob."""
    out = []
    for t in TARGETS:
        for s in range(seeds):
            spec = SessionSpec(width=800, height=600, k1=-0.2, views=views, seed=11 + s,
                               size_range=(0.4, 0.7) if t == "pascal_board_a3" else (0.3, 0.6))
            out.append(BiasCase(f"{t}, k1 -0.2, plumb_bob", t, spec, "plumb_bob", False))
    wide = lens_cases(views, seed=1)[1].spec
    fish = replace(lens_cases(views, seed=1)[0].spec, focal=420.0, pixel_range=(0.1, 0.9))
    for s in range(3):
        out.append(BiasCase("rational 115 deg lens, plumb_bob", "ring_grid_a4", replace(wide, seed=21 + s),
                            "plumb_bob", True))
        out.append(BiasCase("fisheye 120 deg lens, plumb_bob", "ring_grid_a4", replace(fish, seed=31 + s),
                            "plumb_bob", True))
    return out


def run_case(case: BiasCase) -> dict[str, Any]:
    """Render, calibrate and judge one session."""
    target = resolve_target(case.target)
    cam = case.spec.camera()
    dets = [detect_target(render_view(target, cam, pose, sens, case.spec.sheet_shape(target)).image, target, name=n)
            for n, pose, sens in session_views(target, case.spec)]
    row: dict[str, Any] = {"case": case.label, "target": case.target, "seed": case.spec.seed,
                           "model_cannot_fit": case.biased}
    try:
        res = calibrate(dets, target, CalibrationOptions(distortion=case.distortion))
    except CalibrationError as e:
        return {**row, "error": str(e)[:120]}
    s = residual_samples_of(res)
    reg = regional(s, res.size)
    rad = radial(s, (res.K[0, 2], res.K[1, 2]))
    mb = model_bias(reg, rad, res.size, res.model)
    tested = np.isfinite(mb.radial_px)
    return {**row, "views": res.n_used, "rms_px": round(res.rms, 4), "detected": mb.detected,
            "max_regional_px": round(mb.max_regional_px, 4),
            "max_radial_px": round(float(np.max(np.abs(np.asarray(mb.radial_px)[tested]), initial=0.0)), 4),
            "regions_biased": mb.regional_significant, "rings_biased": mb.radial_significant}


def model_bias_study(out: Path, views: int = 12, seeds: int = 4, workers: int = 2) -> list[dict[str, Any]]:
    """Run every case; write ``model_bias.csv`` and print a table and the false-alarm / detection counts."""
    out.mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(workers) as pool:
        rows = list(pool.map(run_case, cases(views, seeds)))
    keys = ["case", "target", "seed", "model_cannot_fit", "views", "rms_px", "max_regional_px", "max_radial_px",
            "regions_biased", "rings_biased", "detected", "error"]
    with open(out / "model_bias.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    print(markdown_table(rows, keys))
    exact = [r for r in rows if not r["model_cannot_fit"] and "detected" in r]
    wrong = [r for r in rows if r["model_cannot_fit"] and "detected" in r]
    print(f"false alarms: {sum(r['detected'] for r in exact)} of {len(exact)} sessions whose lens the model "
          f"describes; detected: {sum(r['detected'] for r in wrong)} of {len(wrong)} sessions whose lens it cannot")
    return rows
