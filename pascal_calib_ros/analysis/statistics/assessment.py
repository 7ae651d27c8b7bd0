"""What analysis says about a calibration: its projection uncertainty and the model-bias verdict.

:func:`assess` takes a :class:`~..calibrate.result.CalibrationResult` (the solver's parameters,
covariance and residuals) and adds mrcal's projection uncertainty at a distance
(:mod:`.uncertainty`) and the verdict whether the residuals carry a pattern beyond noise
(:mod:`.residual_stats`). The CLI, the node and the report all read a calibration through it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...calibrate import CalibrationResult
from .residual_stats import ModelBias, ResidualSamples, model_bias, radial, regional, residual_samples
from .uncertainty import ProjectionUncertainty, projection_uncertainty_of


@dataclass
class Assessment:
    """A calibration with its analysis.

    Attributes
    ----------
    result : CalibrationResult
        The calibration as the solver gave it.
    projection : ProjectionUncertainty or None
        Worst-direction pixel sigma over a grid of the image at ``projection.distance`` metres
        (None without a parameter covariance: no refinement).
    bias : ModelBias or None
        The model-bias verdict (None without refined residuals).
    """

    result: CalibrationResult
    projection: ProjectionUncertainty | None
    bias: ModelBias | None

    @property
    def warnings(self) -> list[str]:
        """The solver's warnings and, when a model bias is detected, its hint."""
        out = list(self.result.warnings)
        if self.bias is not None and self.bias.detected and self.bias.hint not in out:
            out.append(self.bias.hint)
        return out

    def projection_summary(self) -> dict[str, float] | None:
        """Median and worst projection sigma (px) over the observed field, and the distance (m)."""
        if self.projection is None:
            return None
        res = self.result
        return self.projection.summary(res.observed_field() if res.edge_points else None)


def residual_samples_of(res: CalibrationResult) -> ResidualSamples:
    """Every edge and corner residual of a calibration as a vector at its pixel."""
    kappa = res.refinement.kappa if res.refinement is not None else (1.0, 1.0)
    return residual_samples(res.edge_points, res.edge_residuals, res.edge_circles, res.corner_points,
                            res.corner_residuals, kappa)


def model_bias_of(res: CalibrationResult) -> ModelBias:
    """The verdict whether the residuals of a calibration carry a pattern beyond noise."""
    s = residual_samples_of(res)
    return model_bias(regional(s, res.size), radial(s, (float(res.K[0, 2]), float(res.K[1, 2]))),
                      res.size, res.model)


def assess(res: CalibrationResult, distance: float | None = None) -> Assessment:
    """Analyse a calibration.

    Parameters
    ----------
    res : CalibrationResult
        A calibration (:func:`~..calibrate.pipeline.calibrate`).
    distance : float, optional
        Metres at which the projection uncertainty is evaluated; ``inf`` at infinity; default the
        median distance from the camera to the observed target's centre.

    Raises
    ------
    ValueError
        If ``distance`` is not positive.
    """
    if distance is not None and not distance > 0:
        raise ValueError(f"the projection uncertainty's distance must be positive (or inf), not {distance}")
    ref = res.refinement
    projection = None
    if ref is not None and ref.covariance is not None and ref.x is not None:
        projection = projection_uncertainty_of(ref, res.size, distance)
    bias = model_bias_of(res) if res.refined and res.edge_points else None
    return Assessment(res, projection, bias)


