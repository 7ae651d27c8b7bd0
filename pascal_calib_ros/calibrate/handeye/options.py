"""What a hand-eye calibration takes and gives: its options, its result, the error that says why not."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...geometry import Transform
from ...modes import HandEyeMode
from ..intrinsic.result import CalibrationError, CalibrationResult

MIN_VIEWS = 3


MIN_MOTION_DEG = 2.0  # a relative motion rotating less than this carries no axis


MIN_AXIS_SPREAD_DEG = 5.0  # the largest angle between two motion axes must exceed this


class HandEyeError(CalibrationError):
    """The hand-eye session cannot be solved (too few views, degenerate motions, bad poses)."""


@dataclass
class HandEyeOptions:
    mode: HandEyeMode = HandEyeMode.EYE_IN_HAND
    robot_sigma_mm: float = 0.1  # the arm's pose accuracy per axis (start value when estimated)
    robot_sigma_deg: float = 0.01
    estimate_robot_noise: bool = True  # estimate the arm's accuracy from the data (variance components)
    outlier_mm: float = 10.0  # a view whose chain disagrees by more than max(this, 8 x median) is dropped
    outlier_deg: float = 1.0
    jackknife_groups: int = 5  # the sigmas of X and Y also from a delete-a-group jackknife over the views (0: off)
    # "hold": K and D from the images alone, held in the chain refinement (the chain informs X, Y and the poses
    # only; the intrinsics' uncertainty is propagated into the sigmas of X and Y); "joint": estimated with the chain
    intrinsics: str = "hold"
    # the arm's systematic position error, which no session can measure (a smooth field over the workspace: a
    # Gaussian process, per base axis, of this standard deviation and correlation length); its share of the
    # sigmas of X and Y is added (0: left out). A prior from the arm's absolute accuracy, not a measurement
    arm_accuracy_mm: float = 0.2
    arm_accuracy_length: float = 0.3  # m

    def __post_init__(self) -> None:
        try:  # the mode's text (a parameter, an option) becomes the enum; unknown text is refused here
            self.mode = HandEyeMode(self.mode)
        except ValueError:
            raise HandEyeError(f"unknown hand-eye mode {self.mode!r}; choose one of {', '.join(HandEyeMode)}") from None

    def arm_accuracy_problem(self) -> str:
        """Why the arm-accuracy prior cannot be used ("" if it can)."""
        if np.isfinite(self.arm_accuracy_mm) and self.arm_accuracy_mm >= 0 and np.isfinite(self.arm_accuracy_length) \
                and self.arm_accuracy_length > 0:
            return ""
        return (f"arm accuracy {self.arm_accuracy_mm} mm over {self.arm_accuracy_length} m: give a finite accuracy "
                ">= 0 mm and a finite correlation length > 0 m")


@dataclass(frozen=True)
class HandEyeView:
    """One view of a hand-eye session: used or why not, and how far its robot chain disagrees with
    its image (translation mm, rotation deg; NaN where not measured)."""

    name: str
    used: bool
    reason: str = ""
    disagreement_mm: float = float("nan")
    disagreement_deg: float = float("nan")


@dataclass
class HandEyeResult:
    calibration: CalibrationResult
    mode: HandEyeMode
    hand_eye: Transform  # camera -> tool (eye_in_hand) or camera -> base (eye_to_hand)
    translation_std_mm: np.ndarray  # (3,) along the parent frame's axes
    rotation_std_deg: np.ndarray  # (3,) small rotations about the parent frame's axes
    target: Transform  # target (its YAML frame) -> base (eye_in_hand) or -> tool (eye_to_hand)
    views_used: int
    rms_px: float
    robot_error_mm: float  # the arm's pose error per axis the data imply (estimated sigma)
    robot_error_deg: float
    per_view: list[HandEyeView] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    closed_form: Transform | None = None  # X from the closed form (Park-Martin, or the ring's linear start)
    target_std_mm: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    target_std_deg: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    start_K: np.ndarray | None = None  # K of the plain intrinsic calibration (before the joint estimate)
    arm_share_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))  # of translation_std_mm: the arm prior's
    arm_share_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    arm_accuracy_mm: float = 0.0  # the prior used (HandEyeOptions.arm_accuracy_mm / _length)
    arm_accuracy_length: float = 0.0
    # of translation_std_mm / rotation_std_deg: the held intrinsics' share (their error moves X alike in every later
    # estimate with the same intrinsics: pascal-calib verify takes it out of the comparison)
    intrinsics_share_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    intrinsics_share_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def parent_frame_role(self) -> str:
        return "tool" if self.mode == HandEyeMode.EYE_IN_HAND else "base"
