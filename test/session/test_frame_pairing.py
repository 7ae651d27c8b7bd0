"""Pairing two cameras' frames by stamp (session/frame_pairing.py)."""

from __future__ import annotations

import pytest

from pascal_calib_ros.session.frame_pairing import STUCK_FRAMES, ApproximatePairer

MS = 1_000_000


def _feed(pairer: ApproximatePairer, frames: list[tuple[int, int]]) -> tuple[list[tuple[int, int]], list[str]]:
    """Push (side, stamp ms) frames; returns the pairs as (left ms, right ms) and the drop reasons."""
    pairs, drops = [], []
    for side, t in frames:
        got, dropped = pairer.push(side, t * MS, t)
        pairs += [(a.item, b.item) for a, b in got]
        drops += [d.reason for d in dropped]
    return pairs, drops


def test_equal_stamps_pair_in_either_order() -> None:
    p = ApproximatePairer(0.0)
    pairs, drops = _feed(p, [(0, 100), (1, 100), (1, 200), (0, 200)])
    assert pairs == [(100, 100), (200, 200)] and not drops
    assert p.stats.paired == 2 and p.stats.last_pair_gap_s == 0.0


def test_unsynchronised_cameras_pair_within_the_slop_and_the_nearest_frame_wins() -> None:
    # left at 30 Hz, right 10 ms later; then a left frame arrives twice (the older is superseded)
    p = ApproximatePairer(0.02)
    pairs, drops = _feed(p, [(0, 0), (1, 10), (0, 33), (0, 40), (1, 43), (0, 66), (1, 76)])
    assert pairs == [(0, 10), (40, 43), (66, 76)]
    assert drops == ["a newer left frame is closer to the right frame"]
    assert p.stats.dropped == [1, 0]


def test_frames_further_apart_than_the_slop_never_pair_and_say_why() -> None:
    p = ApproximatePairer(0.02)
    frames = [(side, t + (500 if side else 0)) for t in range(0, 1000 * STUCK_FRAMES, 1000) for side in (0, 1)]
    pairs, drops = _feed(p, frames)
    assert not pairs and len(drops) >= STUCK_FRAMES
    assert "no right frame within sync_slop 0.02 s (the next one is 0.500 s later)" in drops
    note = p.stats.never_paired_note(p.slop_s, ("/l", "/r"))
    assert "never pair" in note and "differ by 0.500 s" in note and "sync_slop 0.02 s" in note, note
    # a pair clears the note
    _feed(p, [(0, 10_000), (1, 10_000)])
    assert p.stats.never_paired_note(p.slop_s) == ""


def test_one_silent_camera_is_named_and_its_partner_queue_stays_bounded() -> None:
    p = ApproximatePairer(0.02, queue_size=4)
    pairs, drops = _feed(p, [(0, t) for t in range(0, 1000, 100)])
    assert not pairs and len(p.queues[0]) == 4 and len(drops) == 6
    assert drops[0] == "no right frame arrived within the 4 newest left frames"
    note = p.stats.never_paired_note(p.slop_s, ("/left/image", "/right/image"))
    assert note.startswith("10 frame(s) arrived on /left/image so far but none on /right/image"), note


def test_stamps_going_back_clear_the_queue_and_bad_arguments_are_refused() -> None:
    p = ApproximatePairer(0.0)
    _, drops = _feed(p, [(0, 500), (0, 100)])
    assert drops == ["the left stamps went back in time; queue cleared"]
    pairs, _ = _feed(p, [(1, 100)])
    assert pairs == [(100, 100)]
    with pytest.raises(ValueError, match="sync slop"):
        ApproximatePairer(-0.1)
    with pytest.raises(ValueError, match="side"):
        p.push(2, 0, None)
