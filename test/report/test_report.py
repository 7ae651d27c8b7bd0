import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.spatial import ConvexHull

from pascal_calib_ros.analysis.statistics.assessment import assess
from pascal_calib_ros.calibrate.intrinsic.pipeline import calibrate
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.geometry.model_field import distortion_field
from pascal_calib_ros.io.printable import write_printable
from pascal_calib_ros.report.pages import PAGES, write_report
from pascal_calib_ros.targets import Target, resolve_target


def test_report_pdf_png_and_json(tmp_path: Path, ring_target: Target, ring_session_distorted) -> None:
    _cam, imgs, dets = ring_session_distorted
    res = calibrate(dets, ring_target)
    by_name = {d.name: im for d, im in zip(dets, imgs, strict=True)}
    files = write_report(assess(res), dets, tmp_path, images=by_name.get)
    assert files.png.stat().st_size > 50_000
    # the PDF: one page per topic (count the page objects)
    pdf = files.pdf.read_bytes()
    assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type /Page\b", pdf)) == PAGES == 7
    data = json.loads(files.json.read_text())
    assert data["rms_px"] == res.rms and len(data["residuals"]["per_view_rms_px"]) == res.n_used
    assert data["distortion_field"]["max_px"] > 5  # k1 = -0.3
    assert len(data["distortion_field"]["points"]) > 20 and len(data["distortion_field"]["points"][0]) == 4
    assert set(data["std"]) >= {"fx", "k1"}
    per_circle = data["residuals"]["per_circle_rms_px"]
    assert set(per_circle) == {"ring/outer", "ring/inner"} and all(0 < v < 0.2 for v in per_circle.values())
    # coverage: the observed fraction against a direct union of the views' hulls (matplotlib's
    # point-in-polygon on every pixel centre), and the views per region
    cov = data["coverage"]
    inside = np.zeros(res.width * res.height, bool)
    uv = np.stack(np.meshgrid(np.arange(res.width), np.arange(res.height)), -1).reshape(-1, 2) + 0.0
    for p in res.feature_points():
        hull = ConvexHull(p)
        inside |= MplPath(p[hull.vertices]).contains_points(uv)
    assert abs(cov["observed_fraction"] - inside.mean()) < 0.02
    assert 0.05 < cov["observed_fraction"] < 0.9
    counts = np.array(cov["views_per_region"]["count"])
    assert counts.shape == tuple(cov["views_per_region"]["grid"]) == (6, 8) and counts.max() <= res.n_used
    # residuals as mrcal shows them, and the verdict: this lens is plumb_bob, the model fits
    r = data["residuals"]
    assert np.array(r["regional"]["mean_px"]).shape == (6, 8, 2) and sum(map(sum, r["regional"]["count"])) > 1000
    assert len(r["radial"]["mean_px"]) == 10 and len(r["histogram"]["count"]) == 40
    assert r["model_bias"]["detected"] is False and r["model_bias"]["hint"] == ""
    assert len(r["worst_views"]) == 3 and set(r["worst_views"]) <= set(by_name)
    assert data["lens_model"]["observed_field_inside_valid"] == 1.0
    assert not any("not noise" in w for w in data["warnings"])


def test_report_of_a_checkerboard_uses_its_corners(tmp_path: Path) -> None:
    from pascal_calib_ros.detect.target_detector import detect_target
    from pascal_calib_ros.sim.session import SessionSpec, render_session_views

    target = resolve_target("checkerboard_a4")
    _, views = render_session_views(target, SessionSpec(width=640, height=480, views=6, seed=4,
                                                         size_range=(0.5, 0.8)))
    dets = [detect_target(v.image, target, name=f"v{k}") for k, v in enumerate(views)]
    res = calibrate(dets, target)
    data = json.loads(write_report(assess(res), dets, tmp_path).json.read_text())
    assert data["coverage"]["observed_fraction"] > 0.1  # corners span the field (no edges here)
    assert sum(map(sum, data["residuals"]["regional"]["count"])) == sum(len(c) for c in res.corner_points)


def test_distortion_field_is_zero_without_distortion() -> None:
    _, d = distortion_field(Camera.from_params(500, 500, 320, 240, width=640, height=480))
    assert abs(d).max() < 1e-9


def test_printable_targets_are_at_exact_scale(tmp_path: Path) -> None:
    import re

    for name in ("ring_a4", "pascal_board_a3", "checkerboard_a4"):
        t = resolve_target(name)
        pdf = write_printable(t, tmp_path / f"{name}.pdf").read_bytes()
        box = [float(v) for v in re.search(rb"MediaBox \[ ([\d. ]+) \]", pdf).group(1).split()]
        assert abs(box[2] / 72 * 25.4 - 1000 * t.sheet[0]) < 0.01 and abs(box[3] / 72 * 25.4 - 1000 * t.sheet[1]) < 0.01
        svg = write_printable(t, tmp_path / f"{name}.svg").read_text()
        assert f"{t.name}: sheet" in svg or "50 mm" in svg


@pytest.mark.parametrize("name", ["charuco_a3", "aprilgrid_a3"])
def test_a_printed_marker_board_reads_back_with_its_ids_where_the_layout_puts_them(tmp_path: Path, name: str) -> None:
    """The PNG page (300 dpi) of a ChArUco or an AprilGrid: every marker found by OpenCV's aruco with
    the id the layout gives it, within 0.5 mm of where the layout puts its corners."""
    import cv2

    from pascal_calib_ros.detect.marker_boards import detect_markers

    t = resolve_target(name)
    img = cv2.imread(str(write_printable(t, tmp_path / f"{name}.png")), cv2.IMREAD_GRAYSCALE)
    assert t.board is not None and img.shape[1] == pytest.approx(t.sheet[0] / 0.0254 * 300, abs=2)
    found = detect_markers(img, t.board)  # type: ignore[arg-type]
    layout = t.board.marker_corners()  # type: ignore[union-attr]
    assert sorted(found.ids.tolist()) == sorted(layout)
    px_per_m = img.shape[1] / t.sheet[0]
    err = [np.abs(c - layout[int(k)] * px_per_m).max() / px_per_m
           for k, c in zip(found.ids, found.corners, strict=True)]
    assert max(err) < 5e-4


def test_report_of_an_unrefined_calibration_has_every_page(tmp_path: Path, ring_target: Target, ring_session) -> None:
    from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions

    _cam, _, dets = ring_session
    res = calibrate(dets, ring_target, CalibrationOptions(refine=False))  # closed form only: no residuals
    files = write_report(assess(res), dets, tmp_path)
    assert len(re.findall(rb"/Type /Page\b", files.pdf.read_bytes())) == PAGES
    data = json.loads(files.json.read_text())
    assert data["refined"] is False and data["residuals"]["model_bias"]["detected"] is False
    # coverage from the used detections' edges (no refined residuals to take them from)
    assert 0.05 < data["coverage"]["observed_fraction"] < 0.9 and data["residuals"]["worst_views"] == []
