"""The intrinsic calibration as the CLI and the node run it: calibrate, assess, cross-validate if
asked, and the lines a person reads."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..analysis import Assessment, CrossValidation, assess, cross_validate
from ..calibrate import CalibrationError, CalibrationOptions, calibrate
from ..detect import Detection
from ..io import CameraInfoData
from ..report import projection_line, summary_line
from ..targets import Target
from .outputs import ReportRequest, ResultPaths, WrittenFiles, camera_info_data, write_result_files


@dataclass
class IntrinsicOutcome:
    """A calibration, its assessment, the seconds it took and, when asked for, the cross-validation
    (or why there is none) in the words a person reads."""

    assessment: Assessment
    seconds: float
    cross_validation: CrossValidation | None = None
    cross_validation_lines: list[str] = field(default_factory=list)

    @property
    def halves_agree(self) -> bool | None:
        """None without a cross-validation."""
        return None if self.cross_validation is None else self.cross_validation.agree

    def camera_info(self, camera_name: str) -> CameraInfoData:
        """The CameraInfo data of the calibration (:func:`~.outputs.camera_info_data`)."""
        return camera_info_data(self.assessment.result, camera_name)

    def write(self, paths: ResultPaths, camera_name: str, report: ReportRequest | None = None) -> WrittenFiles:
        """The result's files (:func:`~.outputs.write_result_files`)."""
        return write_result_files(paths, self.assessment, camera_name, report=report)

    def answer(self, yaml_path: str) -> str:
        """The node's ``~/calibrate`` answer: :func:`camera_answer` and the cross-validation's lines."""
        a = self.assessment
        return "; ".join([camera_answer(a, self.seconds, yaml_path, a.warnings), *self.cross_validation_lines])


def camera_answer(a: Assessment, seconds: float, yaml_path: str, warnings: list[str]) -> str:
    """'fx= fy= cx= cy= rms= views= method= time= yaml=; projection sigma ...' and the warnings."""
    text = f"{summary_line(a.result)} time={seconds:.2f}s yaml={yaml_path}; {projection_line(a)}"
    if warnings:
        text += " warnings: " + "; ".join(warnings)
    return text


def cross_validation_lines(dets: list[Detection], target: Target, options: CalibrationOptions
                           ) -> tuple[CrossValidation | None, list[str]]:
    """Two interleaved halves against their projection uncertainty
    (:mod:`..analysis.cross_validation`): the result and its two lines, or None and why it could
    not be done. A disagreement or a refusal is a WARNING, never a failed calibration."""
    try:
        cv = cross_validate(dets, target, options)
    except CalibrationError as e:
        return None, [f"WARNING: cross-validation not possible: {e}"]
    except Exception as e:  # a numerical failure must not cost the calibration
        return None, [f"WARNING: cross-validation failed: {type(e).__name__}: {e}"]
    return cv, [cv.summary_line(), ("" if cv.agree else "WARNING: ") + cv.message]


def run_intrinsic(dets: list[Detection], target: Target, options: CalibrationOptions, *,
                  distance: float | None = None, with_cross_validation: bool = False) -> IntrinsicOutcome:
    """Calibrate ``dets`` (:func:`~..calibrate.pipeline.calibrate`) and assess the result (projection
    uncertainty at ``distance`` metres, default the median distance to the target's centre; the
    model-bias verdict); with ``with_cross_validation`` also the two halves.

    Raises
    ------
    CalibrationError
        When the views cannot be calibrated; the message says why and what to do.
    """
    t0 = time.perf_counter()
    res = calibrate(dets, target, options)
    outcome = IntrinsicOutcome(assess(res, distance), time.perf_counter() - t0)
    if with_cross_validation:
        outcome.cross_validation, outcome.cross_validation_lines = cross_validation_lines(dets, target, options)
    return outcome
