"""One result's files published as one set."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pascal_calib_ros.workflows.result_set import KEEP, ResultStore, new_result_id


def _fill(tag: str):
    def fill(folder: Path) -> None:
        (folder / "cam.yaml").write_text(f"camera {tag}")
        (folder / "hand_eye.yaml").write_text(f"hand-eye {tag}")
    return fill


def test_the_set_is_published_at_once_through_current(tmp_path: Path) -> None:
    store = ResultStore(tmp_path / "out")
    assert store.current() is None
    a = store.write(_fill("a"), now=1_000_000)
    b = store.write(_fill("b"), now=1_000_000)  # the same second: a distinct id
    assert a.id != b.id and b.id.startswith(a.id) and b.id.endswith("-2")
    assert (tmp_path / "out" / "cam.yaml").read_text() == "camera b"
    assert (tmp_path / "out" / "hand_eye.yaml").read_text() == "hand-eye b"
    assert os.readlink(tmp_path / "out" / "cam.yaml") == "current/cam.yaml"
    cur = store.current()
    assert cur is not None and cur.id == b.id and cur.names == ("cam.yaml", "hand_eye.yaml")
    assert (a.folder / "cam.yaml").read_text() == "camera a"  # the previous set is kept


def test_a_failed_set_leaves_the_previous_one_current(tmp_path: Path) -> None:
    store = ResultStore(tmp_path)
    good = store.write(_fill("good"))

    def half(folder: Path) -> None:
        (folder / "cam.yaml").write_text("new camera")
        raise RuntimeError("killed before hand_eye.yaml")
    with pytest.raises(RuntimeError):
        store.write(half)
    assert (tmp_path / "cam.yaml").read_text() == "camera good" and (tmp_path / "hand_eye.yaml").read_text() == (
        "hand-eye good")
    cur = store.current()
    assert cur is not None and cur.id == good.id
    assert not list((tmp_path / "results").glob(".staging-*"))


def test_old_sets_are_pruned_and_ids_are_unique(tmp_path: Path) -> None:
    store = ResultStore(tmp_path, keep=3)
    ids = [store.write(_fill(str(k)), now=2_000_000 + k).id for k in range(5)]
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ids[-3:]
    assert new_result_id(tmp_path / "results", now=2_000_004).endswith("-2")
    assert KEEP >= 10
