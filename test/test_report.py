import json
from pathlib import Path

from pascal_calib_ros.calibrate.diagnostics import distortion_field
from pascal_calib_ros.calibrate.pipeline import calibrate
from pascal_calib_ros.geometry.camera import Camera
from pascal_calib_ros.io.printable import write_printable
from pascal_calib_ros.io.report import write_report
from pascal_calib_ros.targets import Target, resolve_target


def test_report_png_and_json(tmp_path: Path, ring_target: Target, ring_session_distorted) -> None:
    _cam, _, dets = ring_session_distorted
    res = calibrate(dets, ring_target)
    png, js = write_report(res, dets, tmp_path)
    assert png.stat().st_size > 50_000
    data = json.loads(js.read_text())
    assert data["rms_px"] == res.rms and len(data["residuals"]["per_view_rms_px"]) == res.n_used
    assert 0 < data["coverage"]["image_fraction_inside_some_view"] < 1
    assert data["distortion_field"]["max_px"] > 5  # k1 = -0.3
    assert set(data["std"]) >= {"fx", "k1"}
    per_circle = data["residuals"]["per_circle_rms_px"]
    assert set(per_circle) == {"ring/outer", "ring/inner"} and all(0 < v < 0.2 for v in per_circle.values())


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
