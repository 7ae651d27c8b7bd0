"""Detection as the CLI and the node run it: the parameters for a lens model, and a list of images
detected in order (an image whose size differs from the first readable one is rejected)."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from ..detect import Detection, DetectionParams, DetectionRefusal, detect_target
from ..geometry import lens_model
from ..io import ImageReadError, read_grey
from ..targets import Target


def detection_params(distortion: str, gamma: float = 1.0, max_blur: float = 4.0) -> DetectionParams:
    """The detector's parameters for a lens model (a fisheye bends large circles away from
    ellipses: :meth:`DetectionParams.for_lens`), a display gamma and the widest edge accepted (px)."""
    return DetectionParams.for_lens(lens_model(distortion).wide, gamma=gamma, max_blur=max_blur)


def _progress(enabled: bool, k: int, n: int, text: str) -> None:
    if enabled:
        sys.stderr.write(f"\r[{k}/{n}] {text[:70]:<70}")
        sys.stderr.flush()
        if k == n:
            sys.stderr.write("\n")


def detect_images(items: Iterable[tuple[str, np.ndarray | str]], n: int, target: Target, params: DetectionParams,
                  progress: bool = False) -> list[Detection]:
    """Detect ``target`` in (name, grey image or why it cannot be read) items, in order.

    Parameters
    ----------
    items : iterable of (str, ndarray (H, W) or str)
        The view's name and its grey image, or the reason it could not be read.
    n : int
        How many items there are (for the progress line).
    progress : bool
        Write a progress line on stderr.
    """
    dets: list[Detection] = []
    size: tuple[int, int] | None = None
    for k, (name, img) in enumerate(items, 1):
        _progress(progress, k, n, name)
        if isinstance(img, str):
            dets.append(Detection(0, 0, name=name, reason=img, refusal=DetectionRefusal.UNREADABLE_IMAGE))
            continue
        if size is not None and (img.shape[1], img.shape[0]) != size:
            dets.append(Detection(img.shape[1], img.shape[0], name=name, refusal=DetectionRefusal.SIZE_MISMATCH,
                                  reason=f"image size {img.shape[1]}x{img.shape[0]} differs from {size[0]}x{size[1]}"))
            continue
        size = (img.shape[1], img.shape[0])
        dets.append(detect_target(img, target, params, name=name))
    if size is not None:
        for d in dets:
            if d.width == 0:
                d.width, d.height = size
    return dets


def detect_files(paths: list[Path], target: Target, params: DetectionParams, progress: bool = False
                 ) -> list[Detection]:
    """:func:`detect_images` over image files (named by their file name)."""
    def read() -> Iterator[tuple[str, np.ndarray | str]]:
        for p in paths:
            try:
                yield p.name, read_grey(p)
            except ImageReadError as e:
                yield p.name, str(e)

    return detect_images(read(), len(paths), target, params, progress)
