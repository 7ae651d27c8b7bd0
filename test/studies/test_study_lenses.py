"""``study lenses`` on a few views of the fisheye: the table's columns, the CSV, and our result
within loose bounds of the truth."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from pascal_calib_ros.studies.study import LENS_COLUMNS, lenses


def test_lens_study_fisheye_few_views(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = lenses(tmp_path, views=4, seed=1, cases=("equidistant",))
    table = capsys.readouterr().out
    assert table.startswith("| " + " | ".join(LENS_COLUMNS) + " |")
    with open(tmp_path / "lenses.csv", newline="") as f:
        csv_rows = list(csv.DictReader(f))
    assert list(csv_rows[0]) == list(LENS_COLUMNS)
    assert len(csv_rows) == len(rows) == 5  # ring, disc, OpenCV SB, OpenCV SB + cornerSubPix, plumb_bob
    ring = rows[0]
    assert (ring["target"], ring["method"]) == ("ring_grid_a4", "pascal-calib, equidistant")
    assert not ring["error"], ring["error"]
    assert abs(ring["fx_err_pct"]) < 0.5 and abs(ring["fy_err_pct"]) < 0.5
    assert ring["pp_err_px"] < 2.0 and ring["model_err_px"] < 1.0 and ring["rms"] < 0.5
    assert ring["max_ray_deg"] > 60
    assert {r["target"] for r in rows[2:4]} == {"checkerboard_a4"}
    assert "plumb_bob" in rows[4]["method"] and "equidistant" in rows[4]["error"]
