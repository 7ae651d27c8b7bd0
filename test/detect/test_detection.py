"""A detection's refusal: its kind and its words (issue 35)."""

from __future__ import annotations

from dataclasses import replace

from pascal_calib_ros.detect import Detection, DetectionRefusal


def test_a_usable_view_has_no_refusal_kind() -> None:
    d = Detection(640, 480)
    assert d.ok and d.refusal is None
    assert replace(Detection(640, 480, reason="x", refusal=DetectionRefusal.TOO_SMALL), reason="").refusal is None


def test_a_reason_without_its_kind_is_other() -> None:
    d = Detection(640, 480, reason="no robot pose for this view")
    assert not d.ok and d.refusal == DetectionRefusal.OTHER


def test_refuse_sets_the_kind_and_the_words() -> None:
    d = Detection(640, 480).refuse(DetectionRefusal.CUT_BY_BORDER, "ring cut by the image border")
    assert (d.refusal, d.reason, d.ok) == (DetectionRefusal.CUT_BY_BORDER, "ring cut by the image border", False)
    assert str(d.refusal) == "cut by border"  # the kind's text, as files and logs write it
    kept = replace(d, reason="no robot pose for this view")  # a new reason keeps the kind given with it
    assert kept.refusal == DetectionRefusal.CUT_BY_BORDER
