"""Solving only: detections in, parameters (and their covariance) out. The closed forms (circular
points, grid homographies, OpenCV's Zhang), the joint refinement with outlier rejection, the
pipeline that chains them (:func:`calibrate`), hand-eye (:mod:`.handeye`). No I/O, no threads."""

from .intrinsic.initial import PlanePose, pose_from_view, pose_to_params
from .intrinsic.options import METHODS, MIN_VIEWS, CalibrationOptions, observations
from .intrinsic.pipeline import calibrate, target_shape_frame
from .intrinsic.result import CalibrationError, CalibrationResult, ViewReport
from .intrinsic.warm import IntrinsicStart, calibrate_warm
from .rig.calibration import RigOptions, RigResult, calibrate_rig
from .solver.lm import levenberg_marquardt
from .solver.observations import ViewData
from .solver.problem import DISTORTION_MODELS, SHAPE_CHOICES, SHAPE_NAMES, Problem, intrinsic_names
from .solver.refine import OUTLIER_K, RefineResult, refine

__all__ = ["DISTORTION_MODELS", "METHODS", "MIN_VIEWS", "OUTLIER_K", "SHAPE_CHOICES", "SHAPE_NAMES", "CalibrationError",
           "CalibrationOptions", "CalibrationResult", "IntrinsicStart", "PlanePose", "Problem", "RefineResult",
           "RigOptions", "RigResult", "ViewData", "ViewReport", "calibrate", "calibrate_rig", "calibrate_warm",
           "intrinsic_names", "levenberg_marquardt", "observations", "pose_from_view", "pose_to_params", "refine",
           "target_shape_frame"]
