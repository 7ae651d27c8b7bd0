"""The person cases of the guided study (studies/guided_study.py, studies/guided_strategies.py): the wide
lens case, the person's metric placement error, and the guide learning from a refused view."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidates import Placement, place
from pascal_calib_ros.analysis.guide.view_ranking import distinct_from_all
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.studies import guided_strategies as gs
from pascal_calib_ros.studies.guided_study import cases
from pascal_calib_ros.targets import resolve_target


def test_the_wide_case_is_a_single_ring_on_a_wide_lens_held_by_a_person() -> None:
    c = cases(False)["wide"]
    cam = c.spec.camera()
    assert (c.target, cam.width, cam.height) == ("ring_a4", 1280, 720)
    assert cam.K[0, 0] == pytest.approx(640.0)
    assert cam.D[0] == pytest.approx(-0.28)
    assert c.error == gs.PersonError(rotation_deg=3.0, position_m=0.005)
    q = cases(True)["wide"].spec.camera()
    assert (q.width, q.height, q.K[0, 0]) == (640, 360, pytest.approx(320.0))
    assert all(cases(False)[k].error is None for k in ("ring", "grid", "board", "fisheye", "charuco"))


def test_a_metric_person_error_turns_and_moves_the_target_by_its_sigmas() -> None:
    c = cases(False)["wide"]
    cam, target = c.spec.camera(), resolve_target("ring_a4")
    p = Placement((640.0, 360.0), 0.25, 30.0, 45.0, 0.0)
    T0 = place(target, cam, p)
    err = gs.PersonError(rotation_deg=3.0, position_m=0.005)
    rng = np.random.default_rng(0)
    ctr = np.r_[target.rings[0].center, 0.0]
    angles, moves = [], []
    for _ in range(400):
        T = err.pose(target, cam, p, rng)
        angles.append(np.degrees((T.rotation * T0.rotation.inv()).magnitude()))
        moves.append(T.apply(ctr) - T0.apply(ctr))
    # |omega| of a 3-D normal vector of sigma 3 deg: RMS 3 sqrt(3) deg
    assert np.sqrt(np.mean(np.square(angles))) == pytest.approx(3.0 * np.sqrt(3), rel=0.1)
    assert np.std(moves, axis=0) == pytest.approx([0.005] * 3, rel=0.15)


def test_a_relative_person_error_is_the_placement_missed() -> None:
    cam, target = cases(False)["ring"].spec.camera(), resolve_target("ring_a4")
    p = Placement((400.0, 300.0), 0.4, 30.0, 45.0, 0.0)
    err = gs.PersonError()
    T = err.pose(target, cam, p, np.random.default_rng(3))
    want = place(target, cam, err.apply(p, cam.width, np.random.default_rng(3)))
    np.testing.assert_allclose(T.matrix, want.matrix)


def _state(key: str = "wide") -> gs.SessionState:
    c = cases(False)[key]
    return gs.SessionState(resolve_target(c.target), c.spec.camera(), rng=np.random.default_rng(1))


def test_a_refused_bootstrap_view_is_not_asked_again() -> None:
    state = _state()
    guide = gs.Guided(None, cases(False)["wide"].spec)
    guide.next(state)
    first = guide.last
    guide.rejected("no ring found")
    guide.next(state)
    assert guide.last is not None and first is not None
    assert distinct_from_all([guide.last], [first], ImageSize(1280, 720))[0]
    assert guide.repeated == 0 and guide.asked[0]["refused"] == "no ring found"


def test_the_guide_passes_refused_suggestions_as_avoid(monkeypatch: pytest.MonkeyPatch) -> None:
    """After a calibration exists the study's guide asks :func:`suggest_views` with ``avoid``: the
    placements whose views were refused (the node's GuideState.refuse path)."""
    state = _state()
    cal = SimpleNamespace(refinement=SimpleNamespace(covariance=np.eye(2)), size=ImageSize(1280, 720))
    state.calibration = cal  # type: ignore[assignment]
    seen: list[list[Placement]] = []
    offers = [Placement((300.0, 300.0), 0.25, 25.0, 0.0, 0.0), Placement((900.0, 400.0), 0.25, 25.0, 90.0, 0.0)]

    def fake(res: Any, target: Any, size: ImageSize, n: int = 5, avoid: list[Placement] = ()) -> Any:  # type: ignore[assignment]
        seen.append(list(avoid))
        keep = [p for p in offers if distinct_from_all([p], list(avoid), size)[0]] if avoid else offers
        return SimpleNamespace(sigma_px=1.0, suggestions=[SimpleNamespace(placement=p) for p in keep])

    monkeypatch.setattr(gs, "suggest_views", fake)
    guide = gs.Guided(None, cases(False)["wide"].spec)
    guide.next(state)
    assert guide.last == offers[0] and seen[-1] == []
    guide.rejected("no ring found")
    guide.next(state)
    assert seen[-1] == [offers[0]] and guide.last == offers[1]
    assert guide.repeated == 0
