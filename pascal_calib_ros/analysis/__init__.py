"""What a calibration is worth: projection uncertainty (mrcal's), residual statistics and the
model-bias verdict, cross-validation of two halves, the projection difference of two cameras."""

from .assessment import Assessment, assess, model_bias_of
from .compare import CompareError, ProjectionDiff, projection_difference
from .cross_validation import CrossValidation, cross_validate
from .residual_stats import ModelBias
from .uncertainty import ProjectionUncertainty, projection_uncertainty, projection_uncertainty_of

__all__ = ["Assessment", "CompareError", "CrossValidation", "ModelBias", "ProjectionDiff", "ProjectionUncertainty",
           "assess", "cross_validate", "model_bias_of", "projection_difference", "projection_uncertainty",
           "projection_uncertainty_of"]
