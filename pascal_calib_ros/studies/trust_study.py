"""Do the reported standard deviations cover the true error? (``pascal-calib study trust``)

For each scenario kind (ring, board, ring grid, disc grid, JPEG, strong distortion) one session
of poses is rendered ``draws`` times with independent sensor noise (same poses, same camera) and
calibrated each time. Per intrinsic it reports

- ``spread / sigma``: the standard deviation of the estimates over the draws divided by the
  mean reported sigma (1 if sigma describes the noise; the goal is 0.7-1.5);
- ``max |err| / sigma``: the worst true error (estimate - ground truth) in units of that draw's
  own sigma (the goal: at most 3; it also contains any bias that noise does not explain);
- ``bias / sigma``: the mean error over the draws in units of sigma.

This is the check mrcal's documentation asks of any uncertainty estimate (re-solve with
re-sampled noise and compare the spread with the prediction).
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import difference_share, projection_difference, rotation_displacements
from ..calibrate import CalibrationError, CalibrationOptions, CalibrationResult, calibrate
from ..detect import DetectionParams, detect_target
from ..geometry import Camera
from ..sim import SessionSpec, render_view, session_views
from ..targets import resolve_target
from .study import lens_cases

PARAMS = ("fx", "fy", "cx", "cy")


@dataclass(frozen=True)
class TrustScenario:
    name: str
    target: str
    spec: SessionSpec
    distortion: str = "plumb_bob"
    gamma: float = 1.0  # detection linearises with this display gamma (``--gamma``); 1: as the default
    loss: str = "soft_l1"  # the refinement's loss (``--loss``)


def scenarios(views: int) -> tuple[TrustScenario, ...]:
    """The scenario kinds of the trust goals (README, 'Trust')."""
    fisheye = lens_cases(views, seed=1)[0]
    base = SessionSpec(width=800, height=600, k1=-0.2, blur=1.0, views=views, seed=3)
    return (
        TrustScenario("ring, 800x600, k1 -0.2", "ring_a4", base),
        TrustScenario("board A3, 2456x2058, k1 -0.1", "pascal_board_a3",
                      replace(base, width=2456, height=2058, k1=-0.1, blur=1.2, size_range=(0.4, 0.7))),
        TrustScenario("board A3, 1224x1029, k1 -0.1", "pascal_board_a3",
                      replace(base, width=1224, height=1029, k1=-0.1, blur=1.2, size_range=(0.4, 0.7))),
        TrustScenario("ring grid, 800x600, k1 -0.2", "ring_grid_a4", base),
        TrustScenario("ring grid, 800x600, k1 -0.2, --gamma 2.2", "ring_grid_a4", base, gamma=2.2),
        TrustScenario("disc grid, 800x600, k1 -0.2", "disc_grid_a4", base),
        TrustScenario("ring, JPEG 90, blur 1.5", "ring_a4", replace(base, blur=1.5, jpeg=90)),
        TrustScenario("ring, strong distortion k1 -0.45", "ring_a4", replace(base, k1=-0.45, pixel_range=(0.1, 0.9))),
        TrustScenario("ring grid, fisheye 190 deg (equidistant)", "ring_grid_a4", fisheye.spec, fisheye.distortion),
        TrustScenario("ring grid, fisheye 190 deg (equidistant), --gamma 2.2", "ring_grid_a4", fisheye.spec,
                      fisheye.distortion, gamma=2.2),
        TrustScenario("checkerboard, 800x600, k1 -0.2", "checkerboard_a4", base),
        TrustScenario("checkerboard, 800x600, k1 -0.2, --loss linear", "checkerboard_a4", base, loss="linear"),
        TrustScenario("checkerboard, 640x480, k1 -0.2, JPEG 90", "checkerboard_a4",
                      replace(base, width=640, height=480, jpeg=90)),
        TrustScenario("ChArUco, 800x600, k1 -0.2, 4 partial views", "charuco_a3",
                      replace(base, size_range=(0.45, 0.75), partial_views=4)),
        TrustScenario("AprilGrid, fisheye 190 deg (equidistant), 4 partial views", "aprilgrid_a3",
                      replace(fisheye.spec, size_range=(0.35, 0.7), partial_views=4), fisheye.distortion),
    )


def _one_draw(args: tuple[TrustScenario, int, str]) -> dict[str, Any]:
    """Render the scenario with noise draw ``draw`` and calibrate: estimates, sigmas, errors.
    ``mode``: "noise" (the scenario's poses, new noise), "session" (new poses and noise),
    "clean" (the scenario's poses without sensor noise)."""
    sc, draw, mode = args
    target = resolve_target(sc.target)
    spec = replace(sc.spec, seed=sc.spec.seed + 100 * (draw + 1)) if mode == "session" else sc.spec
    cam = spec.camera()
    dets = []
    for k, (name, pose, sens) in enumerate(session_views(target, spec)):
        sens = replace(sens, seed=10_000 * (draw + 1) + k, noise_sigma=0.0 if mode == "clean" else sens.noise_sigma)
        img = render_view(target, cam, pose, sens, spec.sheet_shape(target)).image
        dets.append(detect_target(img, target, name=name, params=DetectionParams(gamma=sc.gamma)))
    try:
        res = calibrate(dets, target, CalibrationOptions(distortion=sc.distortion, loss=sc.loss))
    except CalibrationError as e:
        return {"error": str(e)}
    truth = {"fx": cam.K[0, 0], "fy": cam.K[1, 1], "cx": cam.K[0, 2], "cy": cam.K[1, 2]}
    est = {"fx": res.K[0, 0], "fy": res.K[1, 1], "cx": res.K[0, 2], "cy": res.K[1, 2]}
    return {"est": est, "err": {p: est[p] - truth[p] for p in PARAMS},
            "std": {p: res.std.get(p, np.nan) for p in PARAMS}, "views": res.n_used, "rms": res.rms,
            "projection": projection_against_truth(res, cam) if mode == "session" else None}


def projection_against_truth(res: CalibrationResult, truth: Camera, step: float | None = None) -> dict[str, float]:
    """The calibration's projection error against the true camera, as ``pascal-calib diff`` measures
    a difference (at infinity, over the observed field, after the best-fitting rotation), beside
    the RMS that its covariance predicts for that quantity
    (:func:`~..calibrate.uncertainty.rotation_free_difference_variance`, the calibration's own share
    only: the truth has none). Their ratio is 1 when the projection uncertainty describes the
    error. ``step``: the grid's spacing in pixels (default: 1/40 of the larger image side)."""
    step = step or max(res.width, res.height) / 40.0
    est = res.camera()
    diff = projection_difference(est, truth, region_mask=res.observed_field(), step=step)
    actual = float(np.sqrt(np.mean(np.sum(diff.difference**2, 1))))
    rays = est.unproject(diff.pixels)
    try:
        var = difference_share(res, rays, rotation_displacements(est, rays))
    except CalibrationError:  # no covariance (not refined)
        return {"actual_px": actual, "predicted_px": float("nan"), "ratio": float("nan")}
    predicted = float(np.sqrt(np.mean(var)))
    return {"actual_px": actual, "predicted_px": predicted, "ratio": actual / predicted}


def run_scenario(sc: TrustScenario, draws: int, workers: int = 2) -> dict[str, list[dict[str, Any]]]:
    """``draws`` calibrations of the scenario's session with new noise, ``draws`` of new sessions,
    one of the session without noise; in ``workers`` processes."""
    jobs = [(sc, d, "noise") for d in range(draws)] + [(sc, d, "session") for d in range(draws)] + [(sc, 0, "clean")]
    with ProcessPoolExecutor(workers) as pool:
        out = list(pool.map(_one_draw, jobs))
    return {"noise": out[:draws], "session": out[draws:2 * draws], "clean": out[2 * draws:]}


def summarise(sc: TrustScenario, results: dict[str, list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """One row per intrinsic (module docstring), plus over new sessions the spread of the z-scores
    error / sigma (1 when sigma describes the whole error) and their worst value, and the error of
    the noise-free session in units of sigma (the part of the error that new noise does not vary)."""
    rows = []
    ok = [r for r in results["noise"] if "error" not in r]
    ses = [r for r in results["session"] if "error" not in r]
    clean = [r for r in results["clean"] if "error" not in r]
    ratios = np.array([r["projection"]["ratio"] for r in ses if r.get("projection")])
    ratios = ratios[np.isfinite(ratios)]
    for p in PARAMS:
        est = np.array([r["est"][p] for r in ok])
        err = np.array([r["err"][p] for r in ok])
        std = np.array([r["std"][p] for r in ok])
        z = np.array([r["err"][p] / r["std"][p] for r in ses])
        sigma = float(np.mean(std))
        spread = float(np.std(est, ddof=1)) if len(est) > 1 else float("nan")
        rows.append({"scenario": sc.name, "param": p, "draws": len(ok), "failed": len(results["noise"]) - len(ok),
                     "sigma": sigma, "spread": spread, "spread_over_sigma": spread / sigma,
                     "max_abs_err_over_sigma": float(np.max(np.abs(err) / std)),
                     "bias_over_sigma": float(np.mean(err) / sigma),
                     "noise_free_err_over_sigma": float(clean[0]["err"][p] / sigma) if clean else float("nan"),
                     "sessions": len(ses),
                     "z_spread_sessions": float(np.std(z, ddof=1)) if len(z) > 1 else float("nan"),
                     "max_abs_z_sessions": float(np.max(np.abs(z))) if len(z) else float("nan"),
                     "projection_ratio_median": float(np.median(ratios)) if len(ratios) else float("nan"),
                     "projection_ratio_max": float(np.max(ratios)) if len(ratios) else float("nan")})
    return rows


def trust(out: Path, draws: int = 24, views: int = 12, only: str = "") -> list[dict[str, Any]]:
    """The Monte Carlo table (CSV, JSON and Markdown in ``out``)."""
    from .study import markdown_table, write_rows

    rows: list[dict[str, Any]] = []
    for sc in scenarios(views):
        if only and only not in sc.name:
            continue
        sys.stderr.write(f"{sc.name}: {draws} draws\n")
        rows += summarise(sc, run_scenario(sc, draws))
        sys.stderr.write(markdown_table(rows[-4:], list(rows[-1])) + "\n")
    write_rows(rows, out, "trust")
    return rows
