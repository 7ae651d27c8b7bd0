from pathlib import Path

import pytest

from pascal_calib_ros.targets import TargetError, load_target, packaged_targets_dir, parse_target, resolve_target


def test_packaged_targets_load_and_match_shared_copies() -> None:
    names = sorted(p.stem for p in packaged_targets_dir().glob("*.yaml"))
    assert {"ring_a4", "pascal_board_a3", "checkerboard_a4"} <= set(names)
    ring = resolve_target("ring_a4")
    assert ring.rings[0].outer_radius == 0.080 and ring.rings[0].inner_radius == 0.040
    assert ring.default_method() == "ring"
    board = resolve_target("pascal_board_a3")
    assert board.checkerboard is not None and board.checkerboard.inner_corners == (8, 5)
    assert set(board.methods()) == {"ring", "pt1", "pt2", "huang", "zhang"}
    assert len(board.circles) == 3 and [c.dark_inside for c in board.circles] == [True, False, True]


def _base() -> dict:
    return {"name": "t", "sheet": {"width": 0.3, "height": 0.2},
            "features": [{"type": "ring", "center": [0.15, 0.1], "outer_radius": 0.08, "inner_radius": 0.04}]}


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["features"][0].update(inner_radius=0.09), "must be smaller"),
        (lambda d: d["features"][0].update(center=[0.05, 0.1]), "off the"),
        (lambda d: d["features"][0].update(type="triangle"), "unknown feature type"),
        (lambda d: d["features"][0].pop("outer_radius"), "missing key 'outer_radius'"),
        (lambda d: d["features"][0].update(outer_radius=-1), "positive"),
        (lambda d: d["features"][0].update(outer_radius=80), "implausible"),
        (lambda d: d.update(features=[]), "non-empty"),
        (lambda d: d["features"].append({"type": "disc", "center": [0.2, 0.1], "radius": 0.02}), "overlap"),
        (lambda d: d.pop("sheet"), "missing key 'sheet'"),
        (lambda d: d["features"][0].update(center="middle"), "list of 2 numbers"),
    ],
)
def test_invalid_targets_are_refused_with_a_reason(mutate, message: str) -> None:
    d = _base()
    mutate(d)
    with pytest.raises(TargetError, match=message):
        parse_target(d)


def test_load_target_errors(tmp_path: Path) -> None:
    with pytest.raises(TargetError, match="not found"):
        load_target(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [unclosed\n")
    with pytest.raises(TargetError, match="not valid YAML"):
        load_target(bad)
    bad.write_text("- just\n- a list\n")
    with pytest.raises(TargetError, match="mapping"):
        load_target(bad)


def _installed_layout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """This module as if installed (no package.xml beside it); returns an ament prefix with the
    package's share directory (config/targets/ring_a4.yaml) and its ament index marker."""
    from pascal_calib_ros import targets

    monkeypatch.setattr(targets, "__file__", str(tmp_path / "site-packages" / "pascal_calib_ros" / "targets.py"))
    prefix = tmp_path / "install" / "pascal_calib_ros"
    (prefix / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (prefix / "share" / "ament_index" / "resource_index" / "packages" / "pascal_calib_ros").write_text("")
    (prefix / "share" / "pascal_calib_ros" / "config" / "targets").mkdir(parents=True)
    return prefix


def test_installed_targets_are_found_through_the_ament_index(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ring = packaged_targets_dir() / "ring_a4.yaml"  # the source tree's
    prefix = _installed_layout(tmp_path, monkeypatch)
    (prefix / "share" / "pascal_calib_ros" / "config" / "targets" / "ring_a4.yaml").write_text(ring.read_text())
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{prefix}:{tmp_path / 'underlay'}")
    assert packaged_targets_dir() == prefix / "share" / "pascal_calib_ros" / "config" / "targets"
    assert resolve_target("ring_a4").rings[0].outer_radius == 0.080


def test_missing_packaged_targets_say_where_they_were_looked_for(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    _installed_layout(tmp_path, monkeypatch)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)  # no ament environment: tolerated
    monkeypatch.setattr("sys.prefix", str(tmp_path / "venv"))
    with pytest.raises(TargetError, match=r"packaged target files not found .*venv/share/pascal_calib_ros"):
        resolve_target("ring_a4")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "elsewhere"))  # package not in the index: tolerated
    with pytest.raises(TargetError, match="packaged target files not found"):
        resolve_target("ring_a4")
    (tmp_path / "venv" / "share" / "pascal_calib_ros" / "config" / "targets").mkdir(parents=True)  # pip install
    assert packaged_targets_dir() == tmp_path / "venv" / "share" / "pascal_calib_ros" / "config" / "targets"
