"""The ``pascal-calib`` command as a user runs it (a real subprocess)."""

import json
from pathlib import Path

import pytest
import yaml
from cli_harness import run

from pascal_calib_ros.sim.ground_truth import compare
from pascal_calib_ros.studies.bench import shipped_targets


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("session")
    r = run("render", "--target", "ring_a4", "--out", str(out), "--size", "640x480", "--views", "8", "--k1", "-0.2",
            "--empty-views", "1", "--seed", "4")
    assert r.returncode == 0, r.stderr
    return out


def test_render_writes_images_and_ground_truth(session_dir: Path) -> None:
    truth = json.loads((session_dir / "session.json").read_text())
    assert len(truth["images"]) == 9 and truth["width"] == 640
    assert (session_dir / "view_000.json").exists()


def test_calibrate_writes_yaml_and_reports_each_view(session_dir: Path, tmp_path: Path) -> None:
    (session_dir / "corrupt.png").write_bytes(b"\x89PNG not really")
    out = tmp_path / "cam.yaml"
    r = run("calibrate", "--target", "ring_a4", "--camera-name", "test_cam", "-o", str(out), str(session_dir))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "method: ring (default for target ring_a4)" in r.stdout
    assert "rejected  corrupt.png  " in r.stdout and "not a readable image" in r.stdout
    assert "rejected  empty_000.png  no ring found" in r.stdout
    assert "fx = " in r.stdout and "+-" in r.stdout and "degeneracy ratio" in r.stdout
    doc = yaml.safe_load(out.read_text())
    assert doc["camera_name"] == "test_cam" and doc["distortion_model"] == "plumb_bob"
    err = compare(session_dir / "session.json", out)
    assert abs(err["fx_err_pct"]) < 0.1 and abs(err["cx_err_px"]) < 1 and abs(err["cy_err_px"]) < 1


def test_too_few_views_exit_nonzero_and_write_nothing(session_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "cam.yaml"
    r = run("calibrate", "--target", "ring_a4", "-o", str(out), str(session_dir / "view_000.png"),
            str(session_dir / "view_001.png"), str(session_dir / "empty_000.png"))
    assert r.returncode == 1
    assert "need at least 3" in r.stderr and "no calibration written" in r.stderr
    assert not out.exists()


def test_cross_validate_prints_the_halves_and_a_verdict(session_dir: Path, tmp_path: Path) -> None:
    r = run("calibrate", "--target", "ring_a4", "--cross-validate", "-o", str(tmp_path / "cam.yaml"), str(session_dir))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "projection sigma " in r.stdout and " px median" in r.stdout
    lines = r.stdout.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("cross-validation: 4 against 4 views"))
    assert "at infinity" in lines[i] and "projection difference: rms" in lines[i]
    assert lines[i + 1].startswith("the two halves agree: they differ by "), lines[i + 1]
    # too few views for two halves: said, but the calibration stands (exit 0, YAML written)
    r = run("calibrate", "--target", "ring_a4", "--cross-validate", "--min-views", "5", "-o", str(tmp_path / "b.yaml"),
            str(session_dir))
    assert r.returncode == 0 and (tmp_path / "b.yaml").exists(), r.stdout + r.stderr
    assert "WARNING: cross-validation not possible: 8 usable view(s); cross-validation needs 10" in r.stdout


def test_bad_target_and_missing_images(session_dir: Path, tmp_path: Path) -> None:
    bad = tmp_path / "t.yaml"
    bad.write_text("name: x\nsheet: {width: 0.2, height: 0.2}\nfeatures: [{type: ring, center: [0.1, 0.1], "
                   "outer_radius: 0.05, inner_radius: 0.06}]\n")
    r = run("calibrate", "--target", str(bad), "-o", str(tmp_path / "c.yaml"), str(session_dir))
    assert r.returncode == 2 and "inner_radius" in r.stderr
    r = run("calibrate", "--target", "ring_a4", "-o", str(tmp_path / "c.yaml"), str(tmp_path / "nope.png"),
            str(tmp_path / "nope2.png"), str(tmp_path / "nope3.png"))
    assert r.returncode == 1 and "no such file" in r.stdout
    r = run("calibrate", "--target", "ring_a4", "--method", "zhang", "-o", str(tmp_path / "c.yaml"), str(session_dir))
    assert r.returncode == 1 and "zhang" in r.stderr and "supports: ring" in r.stderr


def test_bench_json_shape() -> None:
    r = run("bench", "--json", "--quick")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert [d["size"] for d in data["detect"]] == ["800x600", "1920x1080", "2456x2058", "1024x768 grid of 70 discs"]
    assert all(d["detect_ms"] > 0 and d["canny_ms"] > 0 for d in data["detect"])
    assert [c["views"] for c in data["calibrate"]] == [3, 10, 20, 20]
    # every shipped target at every size, with its ratio to a Canny pass over the same frames
    rows = data["detect_targets"]
    assert len(rows) == len(shipped_targets()) * 3 and all(r["found"] == r["views"] for r in rows), rows
    # the marker boards against OpenCV's own detection of the same frames
    assert {r["target"] for r in data["marker_boards"]} == {"charuco_a3", "aprilgrid_a3"}
    assert all(r["detect_ms"] > 0 and 0 < r["ratio"] <= r["max_ratio"] for r in data["marker_boards"])
    assert all(r["canny_ms"] > 0 and 0 < r["ratio"] <= r["max_ratio"] for r in rows)
    assert data["first_detection"][0]["seconds"] > 0


def test_target_shape_of_a_bent_sheet(tmp_path: Path) -> None:
    """A ring grid printed on a sheet bent by 1.5 mm: --target-shape finds the bend and says it
    matters; without it the edge RMS is higher."""
    imgs = tmp_path / "imgs"
    r = run("render", "--target", "ring_grid_a4", "--out", str(imgs), "--size", "800x600", "--focal", "600",
            "--views", "10", "--min-size", "0.5", "--max-size", "0.8", "--warp-x", "1.5", "--seed", "2")
    assert r.returncode == 0, r.stderr
    shaped = run("calibrate", "--target", "ring_grid_a4", "--target-shape", "-o", str(tmp_path / "a.yaml"), str(imgs))
    assert shaped.returncode == 0, shaped.stderr
    line = next(ln for ln in shaped.stdout.splitlines() if ln.startswith("target shape:"))
    warp_x = float(line.split("warp along x")[1].split()[0])
    assert abs(warp_x - 1.5) < 0.1, line
    assert "target shape matters" in shaped.stdout
    flat = run("calibrate", "--target", "ring_grid_a4", "-o", str(tmp_path / "b.yaml"), str(imgs))
    rms = [float(next(ln for ln in out.stdout.splitlines() if ln.startswith("RMS:")).split()[1])
           for out in (shaped, flat)]
    assert rms[0] < 0.7 * rms[1], rms
    ring = run("calibrate", "--target", "ring_a4", "--target-shape", "-o", str(tmp_path / "c.yaml"), str(imgs))
    assert ring.returncode != 0 and "cannot be estimated" in ring.stderr
