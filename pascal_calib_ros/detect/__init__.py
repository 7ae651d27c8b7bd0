"""Detection: per view, the target's features at subpixel accuracy (circle edges and their conics,
checkerboard corners) or a refusal: its kind (:class:`DetectionRefusal`) and its reason (:func:`detect_target`)."""

from .checkerboard import refine_corners, right_handed
from .detection import DEFAULT_PARAMS, CircleEdge, Detection, DetectionParams, DetectionRefusal, feature_points
from .marker_boards import aruco_detector, charuco_detector
from .target_detector import BENT_OUTLINE, detect_target

__all__ = ["BENT_OUTLINE", "DEFAULT_PARAMS", "CircleEdge", "Detection", "DetectionParams", "DetectionRefusal",
           "aruco_detector", "charuco_detector", "detect_target", "feature_points", "refine_corners", "right_handed"]
