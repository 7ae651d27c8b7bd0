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


def test_views_of_a_board_without_circles_are_placed_by_its_corners(charuco_session) -> None:
    """A ChArUco (or a plain checkerboard) has no circle: its views are placed and told apart by
    their corners (partial views too); without the board's points they cannot be."""
    import numpy as np

    from pascal_calib_ros.session.collector import NO_PLACE, placement_points, view_parameters
    from pascal_calib_ros.targets import resolve_target

    _, _, dets = charuco_session
    board = placement_points(resolve_target("charuco_a3"))
    assert board is not None and placement_points(resolve_target("pascal_board_a3")) is None  # its ring places it
    ok = [d for d in dets if d.ok]
    c = ViewCollector(min_views=3, board_points=board)
    assert sum(c.offer(d)[0] for d in ok) >= len(ok) - 2
    assert not c.offer(ok[0])[0]  # the same view again is too similar
    p = np.array(c.params)
    assert np.all((p[:, 3] >= 0) & (p[:, 3] < 0.6)) and np.ptp(p[:, 0]) > 0.2  # skew of tilted views; spread in x
    assert view_parameters(ok[0]) is None
    assert ViewCollector().offer(ok[0]) == (False, NO_PLACE)
