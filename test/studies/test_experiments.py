"""The paper's simulation experiments run end to end (few trials) and keep their promises."""

import csv
from pathlib import Path

import numpy as np
import pytest

from pascal_calib_ros.studies.experiments import COLUMNS, SOLVERS, _trial_views, pt2_literal, run_experiment


@pytest.mark.parametrize("name", ["methods", "layouts", "literal"])
def test_experiment_writes_csv_png_and_table(tmp_path: Path, name: str, capsys: pytest.CaptureFixture) -> None:
    rows = run_experiment(name, tmp_path, trials=2, seed=1)
    with open(tmp_path / f"{name}.csv") as f:
        header = next(csv.reader(f))
    assert header[: len(COLUMNS)] == COLUMNS
    assert (tmp_path / f"{name}.png").stat().st_size > 10_000
    assert "std_fu" in capsys.readouterr().out
    sigmas = sorted({r["sigma"] for r in rows})
    assert sigmas[0] == 0.0 and sigmas[-1] == 2.0 and len(sigmas) == 9
    if name == "methods":
        assert {r["method"] for r in rows} == set(SOLVERS) and {r["n_views"] for r in rows} == {3, 10}
        for r in rows:
            if r["sigma"] == 0.0:  # well-posed methods are exact without noise
                assert r["failures"] == 0 and r["std_fu"] < 1e-6 and abs(r["mean_fu"] - 500) < 1e-6, r
    if name == "layouts":
        fitted0 = [r for r in rows if r["sigma"] == 0.0 and r["layout"].endswith("/fitted")]
        assert len(fitted0) == 10 and all(abs(r["mean_fu"] - 500) < 1e-6 for r in fitted0)
    if name == "literal":
        assert {r["method"] for r in rows} == {"pt1_literal", "pt2_literal"}


def test_literal_pt2_converges_to_an_arbitrary_point_of_the_conic() -> None:
    """Without the vanishing line, Newton on PT2 ends on the conic but not at i'."""
    v = _trial_views(0, 0, 0, 1, 0.0)[0]
    from pascal_calib_ros.studies.experiments import layout_points

    five = layout_points(v, "average", "fitted")
    got = pt2_literal(five, np.array([300 + 200j, 250 - 100j, 1.0]))
    C = v.conics["outer"]
    assert abs(got @ C @ got) < 1e-8 * np.abs(got).max() ** 2  # on the conic ...
    assert min(np.abs(got - v.i_true).max(), np.abs(got - np.conj(v.i_true)).max()) > 1.0  # ... not at i'
