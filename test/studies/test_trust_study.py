"""The Monte Carlo summary of the trust study: spread against sigma, z-scores over new sessions."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.studies.trust_study import PARAMS, TrustScenario, scenarios, summarise


def _draw(err: float, std: float) -> dict:
    return {"est": dict.fromkeys(PARAMS, 100.0 + err), "err": dict.fromkeys(PARAMS, err),
            "std": dict.fromkeys(PARAMS, std), "views": 10, "rms": 0.02}


def test_summary_of_known_draws() -> None:
    rng = np.random.default_rng(0)
    noise = [_draw(float(e), 0.5) for e in 0.1 + 0.25 * rng.normal(size=400)]  # spread 0.25 = sigma / 2
    sessions = [_draw(float(e), 0.5) for e in 0.5 * rng.normal(size=400)]  # z ~ N(0, 1)
    rows = summarise(TrustScenario("x", "ring_a4", SessionSpec()),
                     {"noise": [*noise, {"error": "failed"}], "session": sessions, "clean": [_draw(0.1, 0.5)]})
    assert len(rows) == len(PARAMS)
    r = rows[0]
    assert r["draws"] == 400 and r["failed"] == 1
    assert r["spread_over_sigma"] == pytest.approx(0.5, abs=0.05)
    assert r["bias_over_sigma"] == pytest.approx(0.2, abs=0.05)
    assert r["noise_free_err_over_sigma"] == pytest.approx(0.2)
    assert r["z_spread_sessions"] == pytest.approx(1.0, abs=0.1)
    assert np.isnan(r["projection_ratio_median"])  # no projection measured in these draws
    for k, d in enumerate(sessions[:3]):
        d["projection"] = {"actual_px": 0.1 * (k + 1), "predicted_px": 0.1, "ratio": float(k + 1)}
    rows = summarise(TrustScenario("x", "ring_a4", SessionSpec()), {"noise": noise, "session": sessions, "clean": []})
    assert rows[0]["projection_ratio_median"] == 2.0 and rows[0]["projection_ratio_max"] == 3.0


def test_every_scenario_kind_is_covered() -> None:
    names = " ".join(s.name for s in scenarios(12))
    for kind in ("ring", "board", "ring grid", "disc grid", "JPEG", "strong distortion", "fisheye"):
        assert kind in names
    targets = {s.target for s in scenarios(12)}
    assert {"ring_a4", "pascal_board_a3", "ring_grid_a4", "disc_grid_a4"} <= targets


def test_projection_against_truth(ring_target, ring_session) -> None:
    """Against itself a calibration differs by nothing; against the true camera by a finite
    amount, beside a finite predicted RMS."""
    from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
    from pascal_calib_ros.studies.trust_study import projection_against_truth

    cam, _, dets = ring_session
    res = calibrate(dets, ring_target)
    assert projection_against_truth(res, res.camera())["actual_px"] < 1e-6
    p = projection_against_truth(res, cam)
    assert 0 < p["actual_px"] < 0.5 and 0 < p["predicted_px"] < 0.5
    assert p["ratio"] == pytest.approx(p["actual_px"] / p["predicted_px"])
