"""tools/board_vs_mrcal.py (issue 22's benchmark) on a few rendered photos of a checkerboard: every
row is there and near the truth, our pipeline with refinement off is OpenCV's calibrateCamera on our
corners, and the mrcal rows are there when .venv-mrcal runs (else they say why)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pascal_calib_ros.sim.session import SessionSpec, render_session
from pascal_calib_ros.targets import resolve_target

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import board_vs_mrcal
import mrcal_bridge


@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SessionSpec]:
    spec = SessionSpec(width=640, height=480, views=6, k1=-0.2, seed=21, size_range=(0.45, 0.7))
    folder = tmp_path_factory.mktemp("board_photos")
    render_session(resolve_target("checkerboard_a4"), spec, folder)
    return folder, spec


def test_every_row_on_the_same_photos(photos: tuple[Path, SessionSpec]) -> None:
    folder, spec = photos
    out = board_vs_mrcal.run(folder, "checkerboard_a4", "plumb_bob")
    rows = {r["method"]: r for r in out["rows"]}
    truth = spec.camera().K
    assert out["found"]["ours"] == spec.views
    for name in ("ours", "ours, refine off", "opencv, our corners", "opencv, SB corners"):
        r = rows[name]
        assert "error" not in r, r
        assert abs(r["fx"] / truth[0, 0] - 1) < 0.01 and abs(r["cx"] - truth[0, 2]) < 5, r
    # with our refinement off, ours is OpenCV's calibrateCamera on the same corners, to the last digits
    off, cv = rows["ours, refine off"], rows["opencv, our corners"]
    for k in ("fx", "fy", "cx", "cy"):
        assert off[k] == pytest.approx(cv[k], rel=1e-9), k
    assert out["corners_vs_sb"]["views"] >= 1 and out["corners_vs_sb"]["median_px"] < 0.3
    ok, why = mrcal_bridge.available()
    if not ok:
        assert rows["mrcal"]["error"] == why
        return
    m = rows["mrcal"]
    assert abs(m["fx"] / truth[0, 0] - 1) < 0.01
    assert m["sigma_dist"]["median_px"] > 0 and m["sigma_inf"]["worst_px"] >= m["sigma_inf"]["median_px"]
    assert out["distance_m"] == pytest.approx(m["distance_m"])
    # a row with sigma has its ratio to mrcal's; ours has one as soon as the pipeline gives a covariance
    assert "ratio_to_mrcal" in rows["mrcal, no outlier rejection"]
    assert ("ratio_to_mrcal" in rows["ours"]) == bool(np.isfinite(rows["ours"]["sigma_dist"]["median_px"]))
    text = board_vs_mrcal.table(out)
    assert "mrcal, no outlier rejection" in text and "against mrcal" in text
