"""The live result's label, and ~/commit's guard against a stale result."""

from __future__ import annotations

from pascal_calib_ros.session.result_history import ResultHistory


def test_commit_is_refused_before_a_result_and_after_a_failed_attempt() -> None:
    h = ResultHistory()
    assert "call ~/calibrate first" in h.commit_problem() and h.status()["last_attempt"] == "none"
    live = h.succeeded("20261129-101500", 12, at=0.0)
    assert h.commit_problem() == "" and h.status()["result_id"] == "20261129-101500"
    h.attempt_failed("only 2 views", at=60.0)
    problem = h.commit_problem()
    assert problem.startswith("not committed: the last ~/calibrate") and "only 2 views" in problem
    assert live.id in problem and "is older" in problem
    assert h.status()["last_attempt"].startswith("failed at") and h.status()["result_id"] == live.id
    h.succeeded("20261129-101700", 14)
    assert h.commit_problem() == "" and h.status()["last_attempt"] == "succeeded"
