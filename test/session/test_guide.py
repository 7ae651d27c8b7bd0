"""The guided session's state (session/guide.py): bootstrap suggestions before a calibration,
the outline match of a live detection with its hint, done from the real sigma only."""

from __future__ import annotations

import numpy as np
import pytest

from pascal_calib_ros.analysis.guide.candidates import Placement, place
from pascal_calib_ros.analysis.guide.view_ranking import distinct_from_all
from pascal_calib_ros.analysis.statistics.uncertainty import projection_uncertainty_of
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.session.guide import MATCH_OVERLAP, GuideState, hint, overlap
from pascal_calib_ros.sim.render import Pose, SensorModel, render_view
from pascal_calib_ros.sim.session import SessionSpec
from pascal_calib_ros.targets import Target

W, H = 640, 480
TRUE = SessionSpec(width=W, height=H, k1=-0.1).camera()


def _shot(target: Target, T: object, seed: int = 0) -> object:
    img = render_view(target, TRUE, Pose(T.R, T.translation), SensorModel(seed=seed)).image  # type: ignore[attr-defined]
    return detect_target(img, target)


def test_bootstrap_outline_match_and_hint(ring_target: Target) -> None:
    guess = Camera.from_params(W, W, W / 2, H / 2, width=W, height=H)  # a nominal camera, no calibration yet
    g = GuideState(ring_target, guess, goal_sigma_px=0.1)
    assert len(g.suggestions) == 3 and not g.done and not np.isfinite(g.sigma_px)
    s = g.current
    assert s is not None and len(g.outline()) >= 3
    det = _shot(ring_target, s.pose)
    m = g.match(det)
    assert m.overlap >= MATCH_OVERLAP and m.matched and m.hint == "hold still"
    # the target held elsewhere: no match, and the hint names the way to go
    off = place(ring_target, TRUE, Placement((0.72 * W, 0.5 * H), 1.3 * s.placement.distance, 10.0, 0.0, 0.0))
    m2 = g.match(_shot(ring_target, off, 1))
    assert not m2.matched and m2.overlap < 0.5
    assert m2.hint == "move the target left"
    assert g.skip() is g.suggestions[1]


def test_hint_order() -> None:
    sq = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    assert hint(sq, sq + np.array([0.0, 80.0]), 640) == "move the target down"
    assert hint(sq, (sq - 50) * 1.5 + 50, 640) == "bring the target closer"
    assert hint(sq, sq, 640) == "match the outline"
    assert overlap(sq, sq, ImageSize(640, 480)) == pytest.approx(1.0)
    assert overlap(sq, sq + np.array([200.0, 0.0]), ImageSize(640, 480)) == 0.0


def test_done_comes_from_the_recalibrated_views(ring_target: Target) -> None:
    """After the bootstrap views the state recalibrates: its sigma is the real one of those views
    (not the prediction that chose them) and done follows the goal."""
    guess = Camera.from_params(W, W, W / 2, H / 2, width=W, height=H)
    g = GuideState(ring_target, guess, goal_sigma_px=1e-6)
    dets = []
    for k in range(3):
        dets.append(_shot(ring_target, g.suggestions[k].pose, 10 + k))
        g.update(None, ImageSize(W, H), len(dets))
    extra = place(ring_target, TRUE, Placement((0.3 * W, 0.6 * H), g.suggestions[0].placement.distance, 40.0, 200.0,
                                                0.0))
    dets.append(_shot(ring_target, extra, 20))
    res = calibrate(dets, ring_target)
    g.update(res.refinement, ImageSize(W, H), len(dets))
    now = projection_uncertainty_of(res.refinement, res.size)
    assert g.sigma_px == pytest.approx(float(np.nanmax(now.sigma)), rel=1e-4)
    assert not g.done and g.suggestions and all(s.predicted_sigma_px < g.sigma_px for s in g.suggestions)
    g.goal_sigma_px = 2 * g.sigma_px
    assert g.done
    # a recalibration that fails after a view: the next ranked view, never a bootstrap view again
    ranked = [v.placement for v in g.suggestions]
    g.update(None, ImageSize(W, H), len(dets) + 1)
    assert [v.placement for v in g.suggestions] == ranked[1:] and g.index == 0 and not g.done
    assert np.isnan(g.sigma_px) and g.camera is not None


def test_a_refused_view_at_a_suggestion_is_not_offered_again(ring_target: Target) -> None:
    """Issue 36: a view the detector refused at a suggestion makes the guide avoid that
    suggestion's neighbourhood (bootstrap and ranked alike) and offer the next one; the sigma and
    done come from the recalibrated views only, so the refusal changes neither."""
    guess = Camera.from_params(W, W, W / 2, H / 2, width=W, height=H)
    g = GuideState(ring_target, guess, goal_sigma_px=1e-6)
    boot = [s.placement for s in g.suggestions]
    line = g.refuse("no ring found")
    assert "no ring found" in line and g.avoided == [boot[0]] and g.refusals == [line]
    assert g.current is not None and g.current.placement == boot[1]
    g.update(None, ImageSize(W, H), 0)  # the bootstrap again (no view yet): the refused one stays out
    assert [s.placement for s in g.suggestions] == boot[1:] and g.current.placement == boot[1]
    dets = [_shot(ring_target, place(ring_target, TRUE, p), 10 + k) for k, p in enumerate(boot)]
    extra = place(ring_target, TRUE, Placement((0.3 * W, 0.6 * H), boot[0].distance, 40.0, 200.0, 0.0))
    dets.append(_shot(ring_target, extra, 20))
    res = calibrate(dets, ring_target)
    g.update(res.refinement, ImageSize(W, H), len(dets))
    fresh = GuideState(ring_target, guess, goal_sigma_px=1e-6)
    fresh.update(res.refinement, ImageSize(W, H), len(dets))
    sigma, first = g.sigma_px, g.current
    assert first is not None and len(g.suggestions) >= 2
    g.refuse("ring cut by the image border")
    assert g.current is not None and g.current.placement != first.placement
    assert len(g.avoided) == 2 and g.sigma_px == sigma and not g.done
    # ranked again on the same views: nothing in the refused suggestion's neighbourhood, the sigma unchanged
    g.update(res.refinement, ImageSize(W, H), len(dets))
    assert g.suggestions and distinct_from_all([s.placement for s in g.suggestions], [first.placement],
                                               ImageSize(W, H)).all()
    assert g.sigma_px == pytest.approx(sigma, rel=1e-12) and not g.done
    # without the refusal the ranking offers that view again (what the session did before)
    assert fresh.current is not None and fresh.current.placement == first.placement
    assert fresh.sigma_px == pytest.approx(sigma, rel=1e-12)
