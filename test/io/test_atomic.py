"""Files written whole or not at all."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pascal_calib_ros.io.atomic import FileWriteError, replace_symlink, write_bytes_atomic, write_text_atomic


def test_a_file_is_replaced_whole_and_no_temporary_is_left(tmp_path: Path) -> None:
    p = write_text_atomic(tmp_path / "a" / "f.yaml", "old")
    assert p.read_text() == "old"
    write_bytes_atomic(p, b"new")
    assert p.read_bytes() == b"new" and sorted(os.listdir(p.parent)) == ["f.yaml"]


def test_an_unwritable_place_says_why_and_keeps_the_old_file(tmp_path: Path) -> None:
    (tmp_path / "blocker").write_text("a file where a folder should be")
    with pytest.raises(FileWriteError, match=r"cannot write .*blocker/f\.yaml"):
        write_text_atomic(tmp_path / "blocker" / "f.yaml", "x")
    keep = write_text_atomic(tmp_path / "keep.yaml", "old")
    os.chmod(tmp_path, 0o500)
    try:
        if os.access(tmp_path, os.W_OK):  # root ignores the mode
            pytest.skip("running as root: a read-only folder is writable")
        with pytest.raises(FileWriteError, match="Permission denied"):
            write_text_atomic(keep, "new")
    finally:
        os.chmod(tmp_path, 0o700)
    assert keep.read_text() == "old"


def test_a_link_is_swapped_to_its_new_target(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "x").write_text("A")
    (tmp_path / "b" / "x").write_text("B")
    link = replace_symlink(tmp_path / "current", "a")
    assert (link / "x").read_text() == "A"
    replace_symlink(link, "b")
    assert (link / "x").read_text() == "B" and os.readlink(link) == "b"
