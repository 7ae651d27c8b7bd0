"""Files that are either the old version or the new one, never half of either: write a temporary
file in the same folder, flush it to the disk (``fsync``), rename it over the old one (POSIX
``rename`` is atomic within a file system) and flush the folder so that the rename survives a
power cut (the pattern of SQLite's and git's lock files)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from pathlib import Path

from ..errors import PascalCalibError


class FileWriteError(PascalCalibError):
    """A file that could not be written (the reason, with its path)."""


def fsync_folder(folder: Path) -> None:
    """Flush a folder's entries (a rename or a new file in it) to the disk; ignored where folders
    cannot be opened (not POSIX)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _replace(p: Path, tmp: Path, make: Callable[[Path], None], failure: str) -> Path:
    """Make ``tmp`` (``make``), rename it over ``p`` and flush the folder; on an OSError remove
    ``tmp`` and raise :class:`FileWriteError` starting with ``failure``."""
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        make(tmp)
        os.replace(tmp, p)
    except OSError as e:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise FileWriteError(f"{failure}: {e.strerror or e}") from None
    fsync_folder(p.parent)
    return p


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (module docstring), creating the folder. Raises
    :class:`FileWriteError` with the reason."""
    def make(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    p = Path(path)
    return _replace(p, p.with_name(f".{p.name}.{os.getpid()}.tmp"), make, f"cannot write {p}")


def write_text_atomic(path: str | Path, text: str) -> Path:
    """:func:`write_bytes_atomic` of UTF-8 text."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def replace_symlink(link: str | Path, target: str | Path) -> Path:
    """Point the symbolic link ``link`` at ``target`` atomically (a new link renamed over the old
    one; readers see the old target or the new one). ``target`` is stored as given (relative
    targets resolve against the link's folder)."""
    def make(tmp: Path) -> None:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        os.symlink(target, tmp)
    p = Path(link)
    return _replace(p, p.with_name(f".{p.name}.{os.getpid()}.link"), make, f"cannot point {p} at {target}")
