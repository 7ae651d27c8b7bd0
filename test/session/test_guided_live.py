"""The live session's guide (session/guided_live.py) and its drawing (session/guide_overlay.py):
a frame at the suggestion is to be stored, one far from it is not; the update after a stored view
runs on another thread while frames are examined ("computing the next view..."); done only from
the recalibrated views; skip moves on; the live session stores only what the guide lets through."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidates import Placement, place
from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.session.answer import Answer
from pascal_calib_ros.session.guide_overlay import OUTLINE_BGR, draw_guide, guide_lines, progress
from pascal_calib_ros.session.guided_live import COMPUTING, NEAR_OVERLAP, REFUSED_FRAMES, GuidedLive
from pascal_calib_ros.session.live import LiveSession
from pascal_calib_ros.session.overlay import BAR_EMPTY_BGR, bar_rects, draw_live_overlay, state_origin
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import Target

W, H = 640, 480
TRUE = SessionSpec(width=W, height=H, k1=-0.1).camera()


def _frame(target: Target, T: object, seed: int = 0) -> tuple[np.ndarray, object]:
    img = render_view(target, TRUE, Pose(T.R, T.translation), SensorModel(seed=seed)).image  # type: ignore[attr-defined]
    return img, detect_target(img, target)


def _wait(guide: GuidedLive, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while guide.view().computing:
        assert time.monotonic() - t0 < timeout, "the guide's update did not finish"
        time.sleep(0.05)


def test_the_guide_stores_matching_views_and_says_done_from_the_real_sigma(ring_target: Target) -> None:
    guide = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=5.0, n=3)
    session = LiveSession(3, 40, 0.08, 0.0, "auto")
    far = place(ring_target, TRUE, Placement((0.85 * W, 0.8 * H), 1.0, 10.0, 0.0, 0.0))
    _, det_far = _frame(ring_target, far, 99)
    assert not guide.examine(det_far).store  # the first frame makes the state (a nominal camera)
    stored = 0
    for k in range(6):
        v = guide.view()
        assert not v.computing and len(v.outline) >= 3 and v.suggestion
        if v.done:
            break
        # far from the suggestion: not stored, the hint says what to do
        verdict = guide.examine(det_far)
        assert not verdict.store and verdict.line.startswith("match ")
        out = session.examine(det_far, k, None, 0.1, 0.0, drawing=False, guide=Answer(verdict.store, verdict.line))
        assert not out.accepted and "not stored: match" in out.why
        # at the suggestion (the guide's own pose, drawn with the true camera: the bootstrap's guess differs)
        img, det = _frame(ring_target, guide.state.current.pose, 10 + k)  # type: ignore[union-attr]
        verdict = guide.examine(det)
        assert verdict.store, (k, verdict.line)
        out = session.examine(det, 100 + k, None, 0.1, 0.0, drawing=True, guide=Answer(verdict.store, verdict.line))
        assert out.accepted and out.why == f"view {stored} stored"
        stored += 1
        guide.stored(session.snapshot().views)
        assert guide.view().computing or guide.view().count  # (an instant bootstrap update may be over)
        while guide.view().computing:  # frames examined meanwhile are not stored
            assert guide.examine(det).line == COMPUTING
            time.sleep(0.02)
        _wait(guide)
        assert not guide.view().error, guide.view().error
        if stored < 3:
            assert not np.isfinite(guide.view().sigma_px)  # no calibration yet: no sigma, not done
    v = guide.view()
    assert v.done and np.isfinite(v.sigma_px) and v.sigma_px <= 5.0 and stored >= 3
    assert v.update_seconds > 0
    verdict = guide.examine(det_far)
    assert not verdict.store and verdict.line.startswith("DONE")
    # a stricter goal: not done any more (the last real sigma), suggestions ranked with a prediction
    guide.set_goal(1e-4)
    v = guide.view()
    assert not v.done and v.count >= 1 and np.isfinite(v.predicted_sigma_px) and v.predicted_sigma_px < v.sigma_px
    # skip moves on (round robin)
    first = v.suggestion
    now = guide.skip()
    assert (now != first) == (v.count > 1)
    # the picture: the outline drawn in the guide's colour, the lines at the bottom
    pic = draw_live_overlay(img, det, [], {}, 3, 3, False)
    before = pic.copy()
    draw_guide(pic, guide.view(), W)
    changed = np.any(pic != before, axis=2)
    assert changed[H - 40:, :W].any()
    assert np.all(pic[changed] == np.array(OUTLINE_BGR), axis=1).any()
    # the panel: the coverage bars stay, the guide's progress replaces "cover more" (one notion of progress)
    x0, y0, x1, _ = bar_rects(ImageSize(W, H))["skew"]
    assert not changed[:y0 + 10, W:].any()
    _, sy = state_origin(ImageSize(W, H))
    assert changed[sy - 20:sy + 60, W:].any()
    p = progress(guide.view())
    assert 0.0 < p < 1.0 and p == pytest.approx(guide.view().goal_sigma_px / guide.view().sigma_px)
    filled = pic[sy + 20, x0:x1]
    assert abs(np.mean(np.any(filled != np.array(BAR_EMPTY_BGR), axis=1)) - p) < 0.05
    guide.reset()
    assert guide.view().count == 0 and not guide.view().done


def test_the_recalibration_after_a_stored_view_starts_warm_and_gives_the_cold_sigma(
        ring_target: Target, monkeypatch: pytest.MonkeyPatch) -> None:
    import pascal_calib_ros.calibrate.intrinsic.warm as warm

    starts: list[bool] = []
    first = warm._warm_first

    def counted(*a: object, **k: object) -> object:
        out = first(*a, **k)  # type: ignore[arg-type]
        starts.append(out is not None)
        return out

    monkeypatch.setattr(warm, "_warm_first", counted)
    dets = [_frame(ring_target, place(ring_target, TRUE, Placement((u * W, v * H), 0.45, 35.0, a, 0.0)), k)[1]
            for k, (u, v, a) in enumerate([(0.5, 0.5, 0.0), (0.35, 0.4, 120.0), (0.65, 0.6, 240.0),
                                           (0.4, 0.65, 60.0)])]
    assert all(d.ok for d in dets)
    grown = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.01)
    grown.update_now(dets[:3])
    grown.update_now(dets)
    assert starts == [True], starts  # the first call is cold, the second warm
    cold = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.01)
    cold.update_now(dets)
    assert starts == [True]
    a, b = grown.view(), cold.view()
    assert not a.error and not b.error and np.isfinite(a.sigma_px)
    assert a.sigma_px == pytest.approx(b.sigma_px, rel=1e-3)
    grown.reset()  # forgets the start: the next call is cold
    grown.update_now(dets)
    assert starts == [True]


def test_bad_goal_is_refused(ring_target: Target) -> None:
    with pytest.raises(ValueError, match="goal_sigma_px"):
        GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.0)


def test_the_hint_names_the_tilt_once_position_and_distance_agree(ring_target: Target) -> None:
    """Same place and distance, tilted 45 degrees about another axis: the outlines differ in shape
    only, and the hint (from the live target's pose) says which way to tilt."""
    from pascal_calib_ros.analysis.guide.view_ranking import RankedView

    guide = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.1)
    want = Placement((0.5 * W, 0.5 * H), 0.45, 45.0, 0.0, 0.0)
    T_want = place(ring_target, TRUE, want)
    _, det = _frame(ring_target, place(ring_target, TRUE, Placement(want.pixel, 0.45, 45.0, 90.0, 0.0)), 3)
    guide.examine(det)  # makes the state
    guide.state.camera = TRUE  # type: ignore[union-attr]  # as after a calibration
    guide.state.suggestions = [RankedView(T_want, want, float("nan"), np.zeros((0, 0)))]  # type: ignore[union-attr]
    guide.state.index = 0  # type: ignore[union-attr]
    verdict = guide.examine(det)
    assert not verdict.store and verdict.match is not None and verdict.match.overlap < 0.85
    assert verdict.match.hint.endswith("away") and verdict.match.hint.startswith(("tilt", "turn")), verdict.line
    _, det2 = _frame(ring_target, T_want, 4)
    assert guide.examine(det2).store


def test_a_failing_update_is_reported_and_never_leaves_the_guide_computing(ring_target: Target,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    import pascal_calib_ros.session.guided_live as gl

    def broken(*_: object, **__: object) -> None:
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(gl, "calibrate_warm", broken)
    guide = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.1)
    dets = []
    for k in range(3):
        _, det = _frame(ring_target, place(ring_target, TRUE, Placement((0.5 * W, 0.5 * H), 0.5, 30.0, 120.0 * k,
                                                                         0.0)), k)
        guide.examine(det)
        dets.append(det)
    guide.stored(dets)
    _wait(guide)
    v = guide.view()
    assert not v.computing and "LinAlgError" in v.error and not v.done and v.count >= 1
    assert guide.examine(dets[0]).line != COMPUTING


def _refused(ring_target: Target) -> object:
    det = detect_target(np.full((H, W), 200, np.uint8), ring_target)  # a blank sheet: the detector refuses it
    assert not det.ok and det.reason
    return det


def test_a_view_refused_at_the_suggestion_is_reported_and_its_neighbourhood_avoided(ring_target: Target) -> None:
    """collect:=auto: the person reached the suggestion (a usable frame near it), then the detector
    refuses REFUSED_FRAMES frames in a row: the guide says so with the reason (the picture, the
    view for ~/status) and offers the next suggestion, never the refused one again until reset."""
    guide = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.1, watch_refusals=True)
    bad = _refused(ring_target)
    img, near = _frame(ring_target, place(ring_target, TRUE, Placement((0.5 * W, 0.5 * H), 0.5, 30.0, 0.0, 0.0)), 1)
    guide.examine(near)  # makes the state (the nominal camera)
    first = guide.state.current  # type: ignore[union-attr]
    _, at = _frame(ring_target, first.pose, 2)  # type: ignore[union-attr]
    assert guide.examine(at).match.overlap >= NEAR_OVERLAP  # type: ignore[union-attr]
    for _ in range(REFUSED_FRAMES - 1):  # not yet: a few refused frames are a person moving
        assert not guide.examine(bad).line.startswith("refused")
    assert guide.view().avoided == 0 and guide.state.current is first  # type: ignore[union-attr]
    verdict = guide.examine(bad)
    assert not verdict.store and verdict.line.startswith("refused (") and bad.reason in verdict.line
    v = guide.view()
    assert v.avoided == 1 and v.refused == verdict.line and v.index == 0 and v.count == 2
    assert guide.state.current.placement != first.placement  # type: ignore[union-attr]
    pic = draw_live_overlay(img, near, [], {}, 0, 3, False)
    assert any(t == verdict.line for t, _ in guide_lines(v))
    draw_guide(pic, v, W)
    # refused frames without having come near the suggestion: nothing more is refused
    for _ in range(2 * REFUSED_FRAMES):
        guide.examine(bad)
    assert guide.view().avoided == 1
    # a stored view clears the line (the refusal stays in force); reset forgets it
    guide.stored([at])
    _wait(guide)
    assert guide.view().refused == "" and guide.view().avoided == 1
    assert all(s.placement != first.placement for s in guide.state.suggestions)  # type: ignore[union-attr]
    guide.reset()
    guide.examine(near)
    assert guide.view().avoided == 0 and guide.state.current.placement == first.placement  # type: ignore[union-attr]


def test_refused_views_count_neither_in_the_sigma_nor_in_done(ring_target: Target) -> None:
    """The guide's sigma (and so done) is that of the usable views: refused detections among the
    stored views, and a refused suggestion, leave it as it was."""
    dets = [_frame(ring_target, place(ring_target, TRUE, Placement((u * W, v * H), 0.45, 35.0, a, 0.0)), k)[1]
            for k, (u, v, a) in enumerate([(0.5, 0.5, 0.0), (0.35, 0.4, 120.0), (0.65, 0.6, 240.0),
                                           (0.4, 0.65, 60.0)])]
    bad = _refused(ring_target)
    plain = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.01)
    plain.update_now(dets)
    mixed = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=0.01)
    mixed.update_now([dets[0], bad, *dets[1:], bad])
    a, b = plain.view(), mixed.view()
    assert np.isfinite(a.sigma_px) and b.sigma_px == pytest.approx(a.sigma_px, rel=1e-9) and a.done == b.done
    mixed.refuse(bad.reason)
    c = mixed.view()
    assert c.avoided == 1 and c.sigma_px == b.sigma_px and c.done == b.done
    assert c.suggestion != b.suggestion
    # done follows the usable views' real sigma
    mixed.set_goal(1.01 * b.sigma_px)
    assert mixed.view().done
    # too few usable views among many refused ones: no sigma, not done
    few = GuidedLive(ring_target, CalibrationOptions(), goal_sigma_px=1e3)
    few.update_now([dets[0], bad, dets[1], bad, bad])
    assert not np.isfinite(few.view().sigma_px) and not few.view().done
