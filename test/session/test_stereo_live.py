"""The live stereo session's policy (session/stereo_live.py) on a rendered stereo head's detections."""

from __future__ import annotations

import numpy as np
from rig_sessions import det_lists, rendered

from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.session.overlay import panel_width
from pascal_calib_ros.session.stereo_live import StereoSession


def test_shots_both_or_one_camera_sees_duplicates_and_readiness() -> None:
    dets = det_lists("pair")
    s = rendered("pair")
    n = len(s.names)
    session = StereoSession(min_views=3, max_views=40, min_distance=0.08, max_motion_px=0.0)
    out = session.examine((dets[0][0], dets[1][0]), (0, 0), drawing=False)
    assert out.stored and out.why == "shot 0 stored (both cameras)" and out.both == 1
    again = session.examine((dets[0][0], dets[1][0]), (1, 1), drawing=False)
    assert not again.stored and again.why.startswith("too similar to a stored shot")
    assert again.camera_lines[0].startswith("ok; not stored: too similar")
    # a shot the right camera does not see
    empty = Detection(640, 480, reason="no target found")
    out = session.examine((dets[0][1], empty), (2, 2), drawing=False)
    assert out.stored and out.why == ("shot 1 stored: left only (right: no target found); it serves the left "
                                      "camera's intrinsics"), out.why
    assert out.camera_lines == (out.why, "not used: no target found") and out.camera_ok == (True, False)
    out = session.examine((empty, empty), (3, 3), drawing=False)
    assert not out.stored and out.why == "both cameras: no target found"
    for k in range(2, n):
        if dets[0][k].ok and dets[1][k].ok:
            session.examine((dets[0][k], dets[1][k]), (10 + k, 10 + k), drawing=False)
    snap = session.snapshot()
    assert snap.both >= 3 and len(snap.shots) == snap.both + 1
    left, right = snap.detections()
    assert len(left) == len(right) == len(snap.shots)
    assert [d.name for d in left] == [d.name for d in right]  # one shot, one name
    assert sum(not d.ok for d in left + right) == 1  # the single shot's other camera, kept as rejected
    assert snap.rejected == {"too similar to a stored shot": 1, "both cameras: no target found": 1}
    assert session.clear() == len(snap.shots) and session.snapshot().both == 0


def test_picture_shows_both_cameras_side_by_side() -> None:
    dets = det_lists("pair")
    s = rendered("pair")
    session = StereoSession(min_views=3, max_views=40, min_distance=0.08, max_motion_px=0.0)
    out = session.examine((dets[0][0], dets[1][0]), (0, 0), drawing=True)
    pic = session.picture((s.images[0][0], s.images[1][0]), (dets[0][0], dets[1][0]), out)
    h, w = s.images[0][0].shape[:2]
    assert pic is not None and pic.shape == (h, 2 * (w + panel_width(h)), 3)
    # each half is the frame with its own overlay: the right half differs from the left one
    assert not np.array_equal(pic[:, : w + panel_width(h)], pic[:, w + panel_width(h):])


def test_refusal_says_what_is_missing_and_why() -> None:
    session = StereoSession(min_views=5, max_views=40, min_distance=0.08, max_motion_px=0.0)
    snap = session.snapshot()
    text = session.refusal(snap, ["frames arrive but never pair: their stamps differ by 0.500 s"])
    assert text.startswith("0 shot(s) seen by both cameras; need 5") and "differ by 0.500 s" in text
    assert "Move the target" in session.refusal(snap, [])
