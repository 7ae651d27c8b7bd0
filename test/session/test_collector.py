from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.session.collector import ViewCollector


def test_collector_accepts_diverse_views_and_reports_coverage(ring_session) -> None:
    _, _, dets = ring_session
    c = ViewCollector(min_views=5, max_views=8)
    results = [c.offer(d) for d in dets]
    assert sum(ok for ok, _ in results) == 8  # store bounded at max_views
    assert any("full" in why for ok, why in results if not ok)
    cov = c.coverage()
    assert set(cov) == {"x", "y", "size", "skew"} and all(0 <= v <= 1 for v in cov.values())
    assert c.ready == (min(cov.values()) >= 0.5)
    ok, why = c.offer(dets[0])
    assert not ok and "similar" in why
    ok, why = c.offer(Detection(800, 600, reason="no ring found"))
    assert not ok and c.rejected["no ring found"] == 1
    assert c.clear() == 8 and not c.views and c.coverage()["x"] == 0
