"""The stereo study's tables (studies/stereo_study.py) from known rows, and its OpenCV baseline's
corner pairing on a rendered pair."""

from __future__ import annotations

import numpy as np
import pytest
from rig_sessions import GRID, PAIR_SPEC

from pascal_calib_ros.sim.rig import RigSession, rig_shots
from pascal_calib_ros.studies.stereo_study import GOALS, QUANTITIES, _board_pairs, accuracy_table, trust_table
from pascal_calib_ros.targets import resolve_target


def _row(err: float, sigma: float) -> dict:
    return {"est": dict.fromkeys(QUANTITIES, 1.0 + err), "err": dict.fromkeys(QUANTITIES, err),
            "sigma": dict.fromkeys(QUANTITIES, sigma)}


def test_trust_table_of_known_draws() -> None:
    rng = np.random.default_rng(0)
    noise = [_row(float(e), 0.5) for e in 0.1 + 0.25 * rng.normal(size=400)]
    sessions = [_row(float(e), 0.5) for e in 0.5 * rng.normal(size=400)]
    rows = trust_table([*noise, {"error": "failed"}], sessions)
    assert [r["quantity"] for r in rows] == list(QUANTITIES)
    r = rows[0]
    assert r["draws"] == 400 and r["unit"] == "deg" and rows[3]["unit"] == "mm" and rows[6]["unit"] == "px"
    assert r["spread_over_sigma"] == pytest.approx(0.5, abs=0.05)
    assert r["bias_over_sigma"] == pytest.approx(0.2, abs=0.05)
    assert r["z_spread_sessions"] == pytest.approx(1.0, abs=0.1)


def test_accuracy_table_medians_and_goals() -> None:
    rows = [{"method": "a", "rot_err_deg": v, "trans_err_mm": 2 * v, "f_err_pct": v, "c_err_px": v,
             "rot_sigma_deg": 0.1, "trans_sigma_mm": 0.2} for v in (1.0, 2.0, 3.0)] + [{"method": "a", "error": "x"}]
    t = accuracy_table(rows)
    assert t[0]["sessions"] == "3/4" and t[0]["rot_err_deg median"] == 2.0 and t[0]["trans_err_mm worst"] == 6.0
    assert t[-1]["method"].startswith("goal") and t[-1]["rot_err_deg median"] == GOALS["rot_err_deg"]


def test_opencv_baseline_pairs_the_corners_of_both_cameras() -> None:
    """The checkerboard rendered from the rig's shots: both cameras' corners in one order (the
    right camera's grid not found from its other end)."""
    shots, seen = rig_shots(resolve_target(GRID), PAIR_SPEC)
    s = RigSession(PAIR_SPEC, GRID, shots[:4], [f"s{k}" for k in range(4)], seen[:, :4])
    left, right, obj = _board_pairs(s)
    assert len(left) >= 3 and len(obj) == 70
    for a, b in zip(left, right, strict=True):
        assert a.shape == b.shape == (70, 2)
        assert np.dot(a[-1] - a[0], b[-1] - b[0]) > 0
