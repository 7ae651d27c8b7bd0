"""The files of one result written as one set: a kill at any moment leaves the previous set or the
new one, never new intrinsics beside a hand-eye transform solved with the old ones.

Layout of an output folder::

    OUT/results/<id>/          # one folder per result: camera YAML, calibration record, hand_eye.yaml, report
    OUT/current -> results/<id>
    OUT/<camera>.yaml -> current/<camera>.yaml      # the names users and the publisher read
    OUT/hand_eye.yaml -> current/hand_eye.yaml

A set is written into a hidden staging folder, renamed into ``results/`` (a folder rename is
atomic) and published by pointing ``current`` at it (an atomic symlink swap,
:func:`..io.atomic.replace_symlink`); the top-level names are links through ``current``, so one
swap changes every file at once. The newest :data:`KEEP` sets are kept.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..io import FileWriteError, fsync_folder, replace_symlink, write_bytes_atomic

RESULTS = "results"
CURRENT = "current"
KEEP = 20  # result sets kept in results/ (the current one always)
_ID = re.compile(r"^\d{8}-\d{6}(-\d+)?$")


@dataclass(frozen=True)
class ResultSet:
    """A written result: its id (``YYYYmmdd-HHMMSS``, ``-2``... when several in one second), its
    folder, and the files in it by name."""

    id: str
    folder: Path
    names: tuple[str, ...]

    def path(self, name: str) -> Path:
        return self.folder / name


def new_result_id(results: Path, now: float | None = None) -> str:
    """An id not yet used in ``results``: the local time, with a counter if needed."""
    base = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    rid, k = base, 1
    while (results / rid).exists():
        k += 1
        rid = f"{base}-{k}"
    return rid


class ResultStore:
    """The result sets of one output folder (module docstring)."""

    def __init__(self, out_dir: str | Path, keep: int = KEEP) -> None:
        self.out = Path(out_dir).expanduser()
        self.keep = keep

    @property
    def results(self) -> Path:
        return self.out / RESULTS

    def current(self) -> ResultSet | None:
        """The set ``current`` points at (None before the first)."""
        link = self.out / CURRENT
        if not link.is_dir():
            return None
        folder = link.resolve()
        return ResultSet(folder.name, folder, tuple(sorted(p.name for p in folder.iterdir())))

    def write(self, fill: Callable[[Path], object], now: float | None = None) -> ResultSet:
        """Write a new set: ``fill(folder)`` writes its files into a staging folder; then the set is
        published (module docstring). A ``fill`` that raises leaves nothing behind and ``current``
        unchanged; an unwritable folder raises :class:`~..io.atomic.FileWriteError`."""
        try:
            self.results.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise FileWriteError(f"cannot write results into {self.out}: {e.strerror or e}") from None
        rid = new_result_id(self.results, now)
        staging = self.results / f".staging-{rid}-{os.getpid()}"
        try:
            staging.mkdir()
            fill(staging)
            for f in staging.iterdir():  # every file on the disk before the set is published
                with open(f, "rb") as fh:
                    os.fsync(fh.fileno())
            fsync_folder(staging)
            os.rename(staging, self.results / rid)
            fsync_folder(self.results)
        except OSError as e:
            shutil.rmtree(staging, ignore_errors=True)
            raise FileWriteError(f"cannot write results into {self.results}: {e.strerror or e}") from None
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
        folder = self.results / rid
        names = tuple(sorted(p.name for p in folder.iterdir()))
        replace_symlink(self.out / CURRENT, f"{RESULTS}/{rid}")
        for name in names:  # the names users read, once: links through current
            top = self.out / name
            if (folder / name).is_file() and not (top.is_symlink() and os.readlink(top) == f"{CURRENT}/{name}"):
                replace_symlink(top, f"{CURRENT}/{name}")
        self._prune(rid)
        return ResultSet(rid, folder, names)

    def _prune(self, current: str) -> None:
        """Remove the oldest sets beyond :attr:`keep`, and staging folders a kill left behind."""
        sets = sorted(p.name for p in self.results.iterdir() if _ID.match(p.name))
        for name in sets[:max(0, len(sets) - self.keep)]:
            if name != current:
                shutil.rmtree(self.results / name, ignore_errors=True)
        for p in self.results.glob(".staging-*"):
            if not p.name.endswith(f"-{os.getpid()}"):
                shutil.rmtree(p, ignore_errors=True)


def copy_atomic(src: Path, dst: str | Path) -> Path:
    """Copy a file of a result set to a path the user asked for (``calibration_file``), atomically."""
    try:
        return write_bytes_atomic(Path(dst).expanduser(), src.read_bytes())
    except OSError as e:
        raise FileWriteError(f"cannot copy {src} to {dst}: {e.strerror or e}") from None
