"""Solving only: detections in, parameters (and their covariance) out. The closed forms (circular
points, grid homographies, OpenCV's Zhang), the joint refinement with outlier rejection, the
pipeline that chains them (:func:`calibrate`), hand-eye (:mod:`.handeye`). No I/O, no threads."""

from .options import METHODS, CalibrationOptions
from .pipeline import calibrate
from .problem import DISTORTION_MODELS, SHAPE_CHOICES, SHAPE_NAMES
from .refine import RefineResult, refine
from .result import CalibrationError, CalibrationResult, ViewReport

__all__ = ["DISTORTION_MODELS", "METHODS", "SHAPE_CHOICES", "SHAPE_NAMES", "CalibrationError", "CalibrationOptions",
           "CalibrationResult", "RefineResult", "ViewReport", "calibrate", "refine"]
