"""Image files to grey numpy arrays, with clear errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import PascalCalibError

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
