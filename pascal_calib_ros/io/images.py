"""Image files to grey numpy arrays, with clear errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import PascalCalibError
from .atomic import FileWriteError, write_bytes_atomic

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


class ImageReadError(PascalCalibError):
    """The file is missing, unreadable or not an image."""


def read_grey(path: str | Path) -> np.ndarray:
    """Read an image file as 8-bit (or 16-bit) grey. Raises :class:`ImageReadError`."""
    p = Path(path)
    if not p.is_file():
        raise ImageReadError(f"{p}: no such file")
    data = np.fromfile(str(p), dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise ImageReadError(f"{p}: not a readable image (corrupt or unsupported format)")
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    if img.dtype not in (np.uint8, np.uint16):
        raise ImageReadError(f"{p}: unsupported pixel type {img.dtype}")
    return img


class ImageWriteError(PascalCalibError):
    """An image cannot be written (the folder cannot be made, no permission, disk full, no encoder)."""


def encode_image(img: np.ndarray, suffix: str = ".png") -> bytes:
    """The file bytes of ``img`` in the format of ``suffix`` (:class:`ImageWriteError` when OpenCV
    cannot encode it)."""
    try:
        ok, data = cv2.imencode(suffix, img)
    except cv2.error as e:
        raise ImageWriteError(f"OpenCV cannot encode the image as {suffix}: {e}") from None
    if not ok:
        raise ImageWriteError(f"OpenCV cannot encode the image as {suffix}")
    return data.tobytes()


def write_image(path: str | Path, img: np.ndarray) -> Path:
    """Write ``img`` in the format of ``path``'s suffix, creating the folder, atomically
    (:func:`.atomic.write_bytes_atomic`). Raises :class:`ImageWriteError` with the reason
    (``cv2.imwrite`` only returns False)."""
    p = Path(path)
    try:
        data = encode_image(img, p.suffix or ".png")
    except ImageWriteError as e:
        raise ImageWriteError(f"cannot write {p}: {e}") from None
    try:
        return write_bytes_atomic(p, data)
    except FileWriteError as e:
        raise ImageWriteError(str(e)) from None


def expand_image_args(args: list[str]) -> list[Path]:
    """Files and folders (all images inside, sorted) from the command line."""
    out: list[Path] = []
    for a in args:
        p = Path(a)
        if p.is_dir():
            out.extend(sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES))
        else:
            out.append(p)
    return out
