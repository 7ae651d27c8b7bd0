"""What detection gives: per view, the subpixel edges of the target's circles, checkerboard
corners, or a rejection with its reason; and the parameters of detection. Plain data shared by
the detector (:mod:`.target_detector`), the checkerboard finder and everything downstream."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry import ImageSize


@dataclass(frozen=True)
class DetectionParams:
    max_blur: float = 4.0  # px; wider edges reject the view as too blurred
    min_radius: float = 8.0  # px, smallest accepted semi-minor axis of an outer edge
    border_margin: float = 3.0  # px between any feature and the image border
    working_pixels: int = 1_000_000  # contour search on a copy downscaled to about this size
    edge_spacing: float = 1.5  # px of arc per edge profile
    curvature_correction: bool = True
    gamma: float = 1.0  # linearise intensities with this display gamma before locating edges
    min_edge_strength: float = 4.0  # grey levels per px along a blob outline (print vs shading)
    # how far (relative to its size) a blob outline may depart from an ellipse; a fisheye bends
    # large circles away from conics: the calibration raises it for wide lens models
    ellipse_tolerance: float = 0.03

    @staticmethod
    def for_lens(wide: bool, **kwargs: Any) -> DetectionParams:
        """The parameters for a lens model: a fisheye (``wide``) bends a large circle up to ~10 %
        of its size away from the best ellipse (measured on equidistant renders of ring_a4)."""
        return DetectionParams(ellipse_tolerance=0.12 if wide else 0.03, **kwargs)


@dataclass
class CircleEdge:
    """Subpixel observation of one target circle (index into ``Target.circles``)."""

    circle: int
    points: np.ndarray
    conic: np.ndarray
    width: float  # median blur sigma, px
    rms: float


@dataclass
class Detection:
    """What one view gave: edges of circles, checkerboard corners, or a rejection reason."""

    width: int
    height: int
    edges: list[CircleEdge] = field(default_factory=list)
    # (N, 2) checkerboard inner corners, target order; NaN rows: corners not on a saddle (see note)
    corners: np.ndarray | None = None
    reason: str = ""  # empty when usable
    name: str = ""
    note: str = ""  # what was left out of a usable view
    # a marker board's markers that were used: ids (M,) and corners (M, 4, 2) px (the live picture draws them)
    marker_ids: np.ndarray | None = None
    marker_corners: np.ndarray | None = None
    corners_rejected: int = 0  # a marker board's corners located but not on a saddle (NaN rows among the unseen)

    @property
    def ok(self) -> bool:
        return not self.reason

    def edge(self, circle: int) -> CircleEdge | None:
        for e in self.edges:
            if e.circle == circle:
                return e
        return None

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


DEFAULT_PARAMS = DetectionParams()


def feature_points(det: Detection) -> np.ndarray:
    """(N, 2) feature points of a detection: its edge points and measured checkerboard corners
    (corners the detector rejected are NaN and left out)."""
    parts = [np.asarray(e.points, float).reshape(-1, 2) for e in det.edges]
    if det.corners is not None:
        c = np.asarray(det.corners, float).reshape(-1, 2)
        parts.append(c[np.all(np.isfinite(c), 1)])
    return np.concatenate(parts) if parts else np.zeros((0, 2))
