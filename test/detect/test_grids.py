"""Grid boards of rings and discs: target model, detection and ordering, perspective-correct
centres, calibration on renders and on real photographs."""

from pathlib import Path

import numpy as np
import pytest

from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.detect.detection import Detection
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.camera import Camera, model_error
from pascal_calib_ros.geometry.circular import vanishing_line_huang
from pascal_calib_ros.geometry.conic import Ellipse
from pascal_calib_ros.io.images import read_grey
from pascal_calib_ros.sim.render import Pose, SensorModel, look_at_pose, render_view
from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import Target, TargetError, parse_target, resolve_target

DATA = Path(__file__).resolve().parents[1] / "data" / "cmu_discs"


def _grid_yaml(**change: object) -> dict:
    g = {"type": "ring_grid", "origin": [0.04, 0.04], "rows": 7, "cols": 10, "pitch": 0.03,
         "outer_radius": 0.01, "inner_radius": 0.005}
    g.update(change)
    return {"name": "g", "sheet": {"width": 0.4, "height": 0.3}, "features": [g]}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"inner_radius": 0.01}, "must be smaller"),
        ({"pitch": 0.019}, "overlap"),
        ({"pitch": 0.024}, "nearly touch"),
        ({"rows": 1}, "integer >= 2"),
        ({"cols": 12.5}, "integer >= 2"),
        ({"origin": [0.2, 0.04]}, "off the"),
        ({"type": "disc_grid", "radius": -1}, "positive"),
    ],
)
def test_invalid_grids_are_refused(change: dict, message: str) -> None:
    with pytest.raises(TargetError, match=message):
        parse_target(_grid_yaml(**change))


def test_grid_targets_shipped() -> None:
    rg, dg = resolve_target("ring_grid_a4"), resolve_target("disc_grid_a4")
    assert len(rg.circles) == 140 and len(dg.circles) == 70
    assert rg.default_method() == "grid" and dg.default_method() == "grid"
    assert "ring" in rg.methods() and "huang" in dg.methods()
    assert rg.circles[rg.grid_circle_index(0, 6, 9) + 1].feature == "ring_grid[6,9]/inner"


def _true_index(target: Target, cam: Camera, pose: Pose, uv: np.ndarray) -> tuple[int, int]:
    g = target.grids[0]
    C = g.centers()
    X = (pose.R @ np.c_[C, np.zeros(len(C))].T).T + pose.t
    k = int(np.argmin(np.linalg.norm(cam.project(X) - uv, axis=1)))
    return k // g.cols, k % g.cols


def _labels_are_a_lattice_isometry(target: Target, cam: Camera, pose: Pose, det: Detection) -> bool:
    """label = R (true index) + t with R a rotation by 0 or 180 degrees, the same for every element
    (the correspondences a symmetric grid allows; no mirror, no mix-up)."""
    pairs = []
    for e in det.edges:
        c = target.circles[e.circle]
        if not c.dark_inside:
            continue
        r, col = (int(v) for v in c.feature.split("[")[1].split("]")[0].split(","))
        el = Ellipse.from_conic(e.conic)
        pairs.append((np.array(_true_index(target, cam, pose, np.array([el.cx, el.cy]))), np.array([r, col])))
    for sign in (1, -1):
        t = pairs[0][1] - sign * pairs[0][0]
        if all(np.array_equal(lab, sign * tru + t) for tru, lab in pairs):
            return True
    return False


@pytest.mark.parametrize("name", ["ring_grid_a4", "disc_grid_a4"])
def test_grid_detection_under_strong_distortion_and_clutter(name: str) -> None:
    target = resolve_target(name)
    spec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=4, seed=2, size_range=(0.5, 0.85),
                       tilt_range=(10, 45))
    cam, views = render_session_views(target, spec)
    for v in views:
        det = detect_target(v.image, target)
        assert det.ok, det.reason
        n = len({e.circle for e in det.edges if target.circles[e.circle].dark_inside})
        assert n >= 50  # elements touching the border are left out
        assert v.pose is not None and _labels_are_a_lattice_isometry(target, cam, v.pose, det)


def test_partial_board_keeps_the_unambiguous_elements() -> None:
    target = resolve_target("disc_grid_a4")
    cam = Camera.from_params(700, 700, 320, 240, width=640, height=480)
    pose = look_at_pose(target, cam, (80, 240), 0.9, 20.0, 60.0, 5.0)  # left part out of the frame
    det = detect_target(render_view(target, cam, pose, SensorModel(seed=1)).image, target)
    assert det.ok, det.reason
    n = len(det.edges)
    assert 10 <= n < 70
    assert _labels_are_a_lattice_isometry(target, cam, pose, det)


def test_perspective_bias_of_centroids_and_exact_centres() -> None:
    """A strongly tilted view: fitted-ellipse centres miss the image of the circle centre by more
    than 0.2 px; the pole of the vanishing line (from two circles' conics) hits it."""
    target = resolve_target("disc_grid_a4")
    cam = Camera.from_params(800, 800, 512, 384, width=1024, height=768)
    pose = look_at_pose(target, cam, (512, 384), 0.7, 60.0, 0.0, 0.0)
    det = detect_target(render_view(target, cam, pose, SensorModel(blur_sigma=0.8, gamma=1.0, seed=3)).image, target)
    assert det.ok, det.reason
    edges = [e for e in det.edges if target.circles[e.circle].dark_inside]
    far = max(((a, b) for a in edges for b in edges), key=lambda p: np.linalg.norm(
        np.array(target.circles[p[0].circle].center) - target.circles[p[1].circle].center))
    line = vanishing_line_huang(far[0].conic, far[1].conic)
    centroid_err, pole_err = [], []
    for e in edges:
        el = Ellipse.from_conic(e.conic)
        # the physical circle (labels of a symmetric grid may be rotated by 180 degrees)
        r, col = _true_index(target, cam, pose, np.array([el.cx, el.cy]))
        centre = target.grids[0].center(r, col)
        truth = cam.project((pose.R @ np.array([*centre, 0.0]) + pose.t)[None])[0]
        centroid_err.append(np.hypot(el.cx - truth[0], el.cy - truth[1]))
        pole = np.linalg.solve(e.conic, line)
        pole_err.append(np.hypot(*(pole[:2] / pole[2] - truth)))
    assert max(centroid_err) > 0.2
    assert np.median(pole_err) < 0.05 and max(pole_err) < 0.15


def test_grid_calibration_on_renders() -> None:
    target = resolve_target("disc_grid_a4")
    spec = SessionSpec(width=1024, height=768, focal=620, k1=-0.43, views=8, seed=5, size_range=(0.45, 0.85),
                       tilt_range=(15, 45))
    cam, views = render_session_views(target, spec)
    dets = [detect_target(v.image, target) for v in views]
    res = calibrate(dets, target)
    assert res.method == "grid" and res.n_used >= 7
    assert abs(res.K[0, 0] / cam.K[0, 0] - 1) < 1e-3 and np.hypot(*(res.K[:2, 2] - cam.K[:2, 2])) < 1.5
    assert model_error(cam, Camera(res.K, res.D), ImageSize(1024, 768)) < 1.5


def test_real_cmu_photographs() -> None:
    """No reference calibration exists: all 70 discs found in every photo, small residuals, small
    uncertainty, and two disjoint subsets agree."""
    target = resolve_target("disc_grid_a4")
    files = sorted(DATA.glob("*.png"))
    assert len(files) == 10
    dets = [detect_target(read_grey(f), target, name=f.name) for f in files]
    for d in dets:
        assert d.ok, (d.name, d.reason)
        assert len(d.edges) == 70
    res = calibrate(dets, target)
    assert res.n_used == 10 and res.rms < 0.15
    assert res.std["fx"] < 1.0 and res.std["cx"] < 1.0
    assert -0.5 < res.D[0] < -0.35  # strong barrel distortion
    a = calibrate(dets[:5], target)  # set 1
    b = calibrate(dets[5:], target)  # set 2
    assert abs(a.K[0, 0] - b.K[0, 0]) < 1.0 and np.hypot(*(a.K[:2, 2] - b.K[:2, 2])) < 1.5
