"""Refusals as a kind and a message (session/rejection.py): the collector names the kind of every
refusal, counts them by message without the per-frame figures, and only a refusal of the view
itself is what a guide must not suggest again."""

from __future__ import annotations

from dataclasses import replace

from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.session.collector import ViewCollector
from pascal_calib_ros.session.rejection import Rejection, RejectionKind


def test_the_kind_says_whether_the_view_itself_was_refused() -> None:
    assert RejectionKind.TARGET.is_the_view and RejectionKind.IMAGE_SIZE.is_the_view
    assert not RejectionKind.MOVING.is_the_view and not RejectionKind.NO_POSE.is_the_view
    r = Rejection(RejectionKind.MOVING, "moving (target moved 2.00 px between frames)")
    assert r.key == "moving" and str(r) == r.message


def test_the_collector_names_the_kind_of_every_refusal(ring_session) -> None:
    _, _, dets = ring_session
    col = ViewCollector(max_views=2)
    assert not col.offer(Detection(640, 480, name="x", reason="no ring found")).ok
    assert col.last_rejection == Rejection(RejectionKind.TARGET, "no ring found")
    assert col.offer(dets[0]).ok
    other = replace(dets[1], width=dets[1].width + 2)
    answer = col.offer(other)
    assert not answer.ok and col.last_rejection is not None and col.last_rejection.kind is RejectionKind.IMAGE_SIZE
    assert answer.message == col.last_rejection.message and answer.message.startswith("image size")
    assert not col.offer(dets[0]).ok and col.last_rejection.kind is RejectionKind.TOO_SIMILAR
    assert col.offer(dets[1]).ok
    assert not col.offer(dets[2], force=True).ok and col.last_rejection.kind is RejectionKind.STORE_FULL
    assert col.rejected["no ring found"] == 1 and col.rejected["view store full"] == 1
    col.clear()
    assert col.last_rejection is None and not col.rejected
