"""What a calibration gives: the parameters and their standard deviations, each view's fate, the
residuals, the refinement (solution and covariance); and the error that says why there is none."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import PascalCalibError
from ...geometry import DISTORTION_CHOICES, Camera, ImageSize, observed_field_mask
from ..solver.refine import RefineResult


class CalibrationError(PascalCalibError):
    """The session cannot be calibrated; the message says why and what to do."""


@dataclass
class ViewReport:
    name: str
    used: bool
    reason: str = ""
    rms: float = float("nan")
    edge_offset: float = float("nan")
    # observations left out: corners the detector's check rejected (not on a saddle), and edge points /
    # corners the refinement rejected as outliers
    unmeasured_corners: int = 0
    rejected_edges: int = 0
    rejected_corners: int = 0
    # a marker board's partial view: (corners measured, corners on the board); None for other targets
    board_corners: tuple[int, int] | None = None


@dataclass
class CalibrationResult:
    K: np.ndarray
    D: np.ndarray
    width: int
    height: int
    method: str
    rms: float
    std: dict[str, float]
    degeneracy_ratio: float
    views: list[ViewReport]
    warnings: list[str] = field(default_factory=list)
    K_initial: np.ndarray | None = None
    refined: bool = True
    distortion_model: str = "plumb_bob"  # what was asked for (a DISTORTION_CHOICES key)
    poses: list[np.ndarray] = field(default_factory=list)
    # per used view (same order as the used entries of ``views``): edge points and their signed
    # residuals (px, positive outwards), for reports
    edge_points: list[np.ndarray] = field(default_factory=list)
    edge_residuals: list[np.ndarray] = field(default_factory=list)
    edge_circles: list[np.ndarray] = field(default_factory=list)  # Target.circles index of each point
    circle_names: list[str] = field(default_factory=list)  # feature name of each Target.circles entry
    # estimated target shape (empty unless asked for): value, standard deviation, and how much
    # each intrinsic moved against a fit that assumes the nominal flat sheet (fx, fy, cx, cy, the
    # flat fit's rms_flat and, with the pitch ratio, its pitch_aspect_correlation with fy/fx)
    shape: dict[str, float] = field(default_factory=dict)
    shape_std: dict[str, float] = field(default_factory=dict)
    shape_effect: dict[str, float] = field(default_factory=dict)
    refinement: RefineResult | None = None  # the final refinement (solution, covariance)
    # per used view: checkerboard corners (M, 2) and their residuals (observed - predicted)
    corner_points: list[np.ndarray] = field(default_factory=list)
    corner_residuals: list[np.ndarray] = field(default_factory=list)
    # what the standard deviations in ``std`` are (report.json's std_model)
    std_model: str = ""

    def feature_points(self) -> list[np.ndarray]:
        """Per used view, its edge points and checkerboard corners (N, 2): what the observed field
        is the union of the convex hulls of."""
        out = []
        for k, p in enumerate(self.edge_points):
            c = self.corner_points[k] if k < len(self.corner_points) else np.zeros((0, 2))
            out.append(np.concatenate([np.asarray(p, float).reshape(-1, 2), np.asarray(c, float).reshape(-1, 2)]))
        return out

    def observed_field(self, margin: float = 0.0) -> np.ndarray:
        """(height, width) bool: the union of the used views' convex hulls of feature points."""
        return observed_field_mask(self.feature_points(), self.size, margin)

    @property
    def model(self) -> str:
        """The ROS ``distortion_model`` of D (plumb_bob, rational_polynomial, equidistant)."""
        return DISTORTION_CHOICES[self.distortion_model][0].name

    def camera(self) -> Camera:
        return Camera(self.K, self.D, self.width, self.height, self.model)

    def edge_count(self, view: ViewReport) -> int:
        """The number of edge points a used view contributed (0 for a corner-only view)."""
        used = [v for v in self.views if v.used]
        k = next((i for i, v in enumerate(used) if v is view), None)
        return len(self.edge_points[k]) if k is not None and k < len(self.edge_points) else 0

    @property
    def n_used(self) -> int:
        return sum(v.used for v in self.views)

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)
