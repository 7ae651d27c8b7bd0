"""What detection gives: per view, the subpixel edges of the target's circles, checkerboard
corners, or a rejection with its reason; and the parameters of detection. Plain data shared by
the detector (:mod:`.target_detector`), the checkerboard finder and everything downstream."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
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


class DetectionRefusal(StrEnum):
    """What a refused view's reason concerns (the kind; ``Detection.reason`` is the detail a
    person reads). The feature's own state first, then the image, then what is outside detection."""

    NO_TARGET = "no target"  # no shape of the target's features in view (nothing ring-, disc-, grid-like)
    CUT_BY_BORDER = "cut by border"  # a feature is cut by the image border
    NEAR_BORDER = "near border"  # a feature whole in view, its edge too close to the border to be measured
    TOO_SMALL = "too small"  # a feature imaged smaller than the detector measures
    TOO_BLURRED = "too blurred"  # a feature's edge wider than the widest accepted (DetectionParams.max_blur)
    EDGE_NOT_FOUND = "edge not found"  # a feature's edge missing along much of it (occlusion, low contrast)
    NOT_CONCENTRIC = "not concentric"  # a ring's outline and hole not the image of concentric circles
    OUTLINE_NOT_ELLIPSE = "outline not ellipse"  # a ring-like shape whose outline is no ellipse
    AMBIGUOUS = "ambiguous"  # several candidates of the feature, or an inconsistent grid labelling
    TOO_FEW_FEATURES = "too few features"  # a grid or board seen, but too few of its elements or corners measured
    MIRRORED = "mirrored"  # a marker board seen mirrored
    NO_CONTRAST = "no contrast"  # the image is (nearly) uniform
    UNREADABLE_IMAGE = "unreadable image"  # empty, invalid, too small an image, or a file that cannot be read
    MISSING_IMAGE = "missing image"  # no image of this shot (a rig's camera)
    SIZE_MISMATCH = "size mismatch"  # an image of another size than the session's
    UNSUPPORTED = "unsupported"  # a target the detector does not handle
    NO_ROBOT_POSE = "no robot pose"  # hand-eye: the view has no robot pose
    OTHER = "other"  # any other reason (a reason given without its kind)


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
    """What one view gave: edges of circles, checkerboard corners, or a refusal: its kind
    (``refusal``) and the words a person reads (``reason``). Given only a reason, the kind is
    OTHER; without a reason there is no kind. Refuse a view with :meth:`refuse`."""

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
    refusal: DetectionRefusal | None = None  # the kind of the refusal; None when usable

    def __post_init__(self) -> None:
        if not self.reason:
            self.refusal = None
        elif self.refusal is None:
            self.refusal = DetectionRefusal.OTHER

    def refuse(self, kind: DetectionRefusal, reason: str) -> Detection:
        """Refuse the view: its kind and reason set (returns the detection)."""
        self.refusal, self.reason = kind, reason
        return self

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
