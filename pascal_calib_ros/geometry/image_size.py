"""An image's size: one value where width and height travel together."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class ImageSize(NamedTuple):
    """Width (columns) and height (rows) in pixels, as ``sensor_msgs/CameraInfo`` names them; a
    tuple, so ``width, height = size`` unpacks it."""

    width: int
    height: int

    @classmethod
    def of(cls, image: np.ndarray) -> ImageSize:
        """The size of an image array (rows, columns[, channels])."""
        return cls(int(image.shape[1]), int(image.shape[0]))

    def __str__(self) -> str:
        return f"{self.width}x{self.height}"
