"""The undesigned-views study (issue 36) on a small session: half-size images, one seed."""

from __future__ import annotations

import numpy as np

from pascal_calib_ros.studies.undesigned_views import undesigned_spec, undesigned_views, view_truth
from pascal_calib_ros.targets import resolve_target


def test_the_study_classifies_every_view_with_the_truth(capsys) -> None:
    out = undesigned_views(seeds=(1,), scale=0.5, views=3, extras=1)
    rows, (seed,) = out["rows"], out["seeds"]
    assert [r["name"] for r in rows] == ["view_000", "view_001", "view_002", "cut_000", "defocused_000"]
    assert seed["views"] == 5 and seed["measured"] == sum(r["measured"] for r in rows)
    assert seed["whole_measured"] == sum(r["measured"] for r in rows if r["whole"])
    cut = rows[3]
    assert not cut["whole"] and cut["margin"] < 0 and not cut["measured"] and cut["refusal"]
    for r in rows:
        assert r["measured"] == (r["refusal"] == ""), r
        if r["measured"]:  # the truth's verdict: every point near the true edge, the centre's image close
            assert r["whole"] and r["edge0_sd"] < 1.0 and r["centre_err"] < 2.0, r
            # detected with the renders' gamma: no 0.8 px offset of every edge (gamma 1 before)
            assert abs(r["edge0_mean"]) < 0.1 and abs(r["edge1_mean"]) < 0.1, r
    assert out["whole_refused"] == [r for r in rows if r["whole"] and not r["measured"]]
    assert "ring whole in the image" in capsys.readouterr().out


def test_view_truth_says_whole_or_cut() -> None:
    target = resolve_target("ring_a4")
    spec = undesigned_spec(1, scale=0.5, views=1, extras=1)
    from pascal_calib_ros.sim import session_views

    cam = spec.camera()
    truths = {name: view_truth(target, cam, pose) for name, pose, _ in session_views(target, spec)}
    assert truths["view_000"].whole and truths["view_000"].margin >= 3.0
    assert not truths["cut_000"].whole and truths["cut_000"].margin < 0
    assert 0 <= truths["view_000"].tilt <= 90 and np.isfinite(truths["view_000"].size)
