"""Detection: per view, the target's features at subpixel accuracy (circle edges and their conics,
checkerboard corners) or a rejection with its reason (:func:`detect_target`)."""

from .detection import CircleEdge, Detection, DetectionParams, feature_points
from .target_detector import detect_target

__all__ = ["CircleEdge", "Detection", "DetectionParams", "detect_target", "feature_points"]
