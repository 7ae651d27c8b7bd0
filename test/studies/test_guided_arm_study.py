"""The arm case of the guided study: its simulated cell."""

from __future__ import annotations

import numpy as np

from pascal_calib_ros.sim.arm import ArmSpec
from pascal_calib_ros.studies.guided_arm import MODE, ArmCell, designed_views
from pascal_calib_ros.targets import resolve_target


def test_cells_of_different_sessions_render_different_image_noise() -> None:
    """Each session draws its own image noise, as it draws its own arm noise: a strategy whose
    poses do not depend on the seed (``designed``) must not see one noise draw in every session."""
    target = resolve_target("ring_grid_a4")
    spec = ArmSpec(mode=MODE, width=320, height=240, k1=-0.1, seed=1, systematic_mm=0.0)
    shots = []
    for seed in (1, 2):
        cell = ArmCell(target, spec, seed)
        tool = cell.tool_of(designed_views(target, spec)[0])
        det, reported = cell.shoot(tool)
        assert det.ok, det.reason
        shots.append((det, reported, tool))
    (d1, r1, t1), (d2, r2, t2) = shots
    np.testing.assert_allclose(t1.matrix, t2.matrix)  # the same commanded pose
    assert not np.allclose(r1.matrix, r2.matrix)  # the arm's noise differs
    c1 = {e.circle: e.conic / np.linalg.norm(e.conic) for e in d1.edges}
    c2 = {e.circle: e.conic / np.linalg.norm(e.conic) for e in d2.edges}
    both = sorted(set(c1) & set(c2))
    assert len(both) > 100  # the same circles seen
    diff = max(float(np.max(np.abs(c1[k] - c2[k]))) for k in both)
    assert 0 < diff < 1e-2  # fitted to differently noisy edges


def test_redrawn_views_average_the_noise_of_one_session() -> None:
    """A session's commanded tool poses shot again under fresh noise: one calibration per draw at
    each N the views reach, each with its own noise (the errors differ), all of them sane; the
    summary pools them per strategy and N."""
    from pascal_calib_ros.studies.guided_arm import redraw_session, summarise_redraws

    target = resolve_target("ring_grid_a4")
    spec = ArmSpec(mode=MODE, width=640, height=480, k1=-0.1, seed=3, systematic_mm=0.0)
    cell = ArmCell(target, spec, 3)
    tools = [cell.tool_of(C) for C in designed_views(target, spec)[:8]]
    row = {"strategy": "designed", "seed": 3, "target": "ring_grid_a4",
           "commanded": [[*t.translation, *t.quat] for t in tools]}
    r = redraw_session(row, draws=2, quick=True)
    assert set(r["redraw"]) == {"8"}  # 12 and 20 are beyond the session's views
    a, b = r["redraw"]["8"]
    assert "failed" not in a and "failed" not in b
    assert a["rot_err_deg"] != b["rot_err_deg"]
    for f in (a, b):
        assert f["rot_err_deg"] < 0.1 and f["trans_err_mm"] < 1.0 and f["used"] == 8
    table = summarise_redraws([r])
    assert "| designed | 1 | 8 |" in table


def test_the_cells_noise_levels_reach_the_renders_and_the_arm() -> None:
    """A cell's noise levels (``CellNoise``) set the spec, the arm reports the commanded pose
    without arm noise, and a redrawn session keeps its cell's noise (an arm off by 1 degree per
    axis spoils X, a quiet one does not)."""
    from pascal_calib_ros.studies.guided_arm import CellNoise, redraw_session

    spec = CellNoise(0.5, 0.03, 0.3).spec(4, quick=True)
    assert (spec.sensor_noise, spec.noise_deg, spec.noise_mm, spec.systematic_mm) == (0.5, 0.03, 0.3, 0.0)
    assert (spec.width, spec.height, spec.seed) == (640, 480, 4)
    target = resolve_target("ring_grid_a4")
    quiet = CellNoise(0.0, 0.0, 0.0)
    cell = ArmCell(target, quiet.spec(3, True), 3)
    tools = [cell.tool_of(C) for C in designed_views(target, quiet.spec(3, True))[:8]]
    _, reported = cell.shoot(tools[0])
    np.testing.assert_allclose(reported.matrix, tools[0].matrix, atol=1e-12)
    errors = []
    for arm_deg in (0.0, 1.0):
        row = {"strategy": "designed", "seed": 3, "target": "ring_grid_a4", "noise": {"sensor_noise": 0.0,
               "noise_deg": arm_deg, "noise_mm": 0.0}, "commanded": [[*t.translation, *t.quat] for t in tools]}
        errors.append(redraw_session(row, draws=1, quick=True)["redraw"]["8"][0]["rot_err_deg"])
    assert errors[0] < 0.03 < 0.2 < errors[1]
