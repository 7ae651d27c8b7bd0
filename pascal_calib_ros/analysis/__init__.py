"""What a calibration is worth: projection uncertainty (mrcal's), residual statistics and the
model-bias verdict, cross-validation of two halves, the projection difference of two cameras."""

from .guide.arm_guidance import (
    DISTINCT_ROLL_DEG,
    ArmGoals,
    ArmRanking,
    ArmSuggestion,
    TrustRegion,
    arm_model,
    orientation_spread,
    suggest_arm_views,
)
from .guide.candidates import (
    Feasibility,
    Placement,
    bootstrap_placements,
    default_feasibility,
    distance_for_size,
    feasibility_problem,
    feature_centre,
    outline_points,
    place,
)
from .guide.detector_bias import DETECTOR_BIAS, DetectorBias
from .guide.guidance import Linearisation, ViewPredictor
from .guide.view_ranking import RankedView, distinct_from_all, suggest_views
from .refits.refit import DEFAULT_MAX_ERROR_PX, RefitError, RefitResult, refit_camera
from .refits.refit_splined import CHOICE, refit_splined
from .statistics.assessment import Assessment, assess, model_bias_of, residual_samples_of
from .statistics.compare import CompareError, ProjectionDiff, projection_difference, region_from_report
from .statistics.cross_validation import CrossValidation, cross_validate, difference_share
from .statistics.residual_stats import (
    MIN_EFFECTIVE,
    RADIAL_FLOOR_PX,
    REGIONAL_FLOOR_PX,
    ModelBias,
    Radial,
    Regional,
    ResidualSamples,
    model_bias,
    radial,
    regional,
    views_per_region,
)
from .statistics.rig import assess_rig
from .statistics.uncertainty import (
    ProjectionUncertainty,
    projection_uncertainty,
    projection_uncertainty_of,
    rotation_displacements,
)
from .verification.epipolar import epipolar_rms, epipolar_samples
from .verification.fixed_views import VerifyError
from .verification.hand_eye import HandEyeReference
from .verification.intrinsics import DEFAULT_ALPHA
from .verification.verdict import CHANGED, Verification, verify_calibration

__all__ = ["CHANGED", "CHOICE", "DEFAULT_ALPHA", "DEFAULT_MAX_ERROR_PX", "DETECTOR_BIAS", "DISTINCT_ROLL_DEG",
           "MIN_EFFECTIVE", "RADIAL_FLOOR_PX", "REGIONAL_FLOOR_PX", "ArmGoals", "ArmRanking", "ArmSuggestion",
           "Assessment", "CompareError", "CrossValidation", "DetectorBias", "Feasibility", "HandEyeReference",
           "Linearisation", "ModelBias", "Placement", "ProjectionDiff", "ProjectionUncertainty", "Radial", "RankedView",
           "RefitError", "RefitResult", "Regional", "ResidualSamples", "TrustRegion", "Verification", "VerifyError",
           "ViewPredictor", "arm_model", "assess", "assess_rig", "bootstrap_placements", "cross_validate",
           "default_feasibility", "difference_share", "distance_for_size", "distinct_from_all", "epipolar_rms",
           "epipolar_samples", "feasibility_problem", "feature_centre", "model_bias", "model_bias_of",
           "orientation_spread", "outline_points", "place", "projection_difference", "projection_uncertainty",
           "projection_uncertainty_of", "radial", "refit_camera", "refit_splined", "region_from_report", "regional",
           "residual_samples_of", "rotation_displacements", "suggest_arm_views", "suggest_views", "verify_calibration",
           "views_per_region"]
