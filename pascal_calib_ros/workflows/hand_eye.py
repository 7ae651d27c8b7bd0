"""The hand-eye calibration as the CLI and the node run it: the frames by mode, the joint estimate
and its assessment, whether the node may publish it, and the lines and files it leaves."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..analysis import Assessment, assess
from ..calibrate import CalibrationOptions
from ..calibrate.handeye import HandEyeOptions, HandEyeResult, calibrate_hand_eye
from ..detect import Detection
from ..geometry import Transform
from ..io import CameraInfoData, HandEyeRecord
from ..modes import HandEyeMode
from ..targets import Target
from .intrinsic import camera_answer
from .outputs import ReportRequest, ResultPaths, WrittenFiles, camera_info_data, write_result_files

MAX_HAND_EYE_STD_MM = 5.0  # a hand-eye transform less certain than this is not published
MAX_HAND_EYE_STD_DEG = 0.5


@dataclass(frozen=True)
class HandEyeFrames:
    """The frames of a hand-eye result: X = parent_T_camera (``parent``: the tool eye in hand, the
    base eye to hand); the target is fixed in ``target`` (the other of the two)."""

    parent: str
    camera: str
    target: str


def hand_eye_frames(mode: HandEyeMode, base_frame: str, tool_frame: str, camera_frame: str) -> HandEyeFrames:
    """The frames of ``mode``'s result (:class:`HandEyeFrames`)."""
    if mode == HandEyeMode.EYE_IN_HAND:
        return HandEyeFrames(tool_frame, camera_frame, base_frame)
    return HandEyeFrames(base_frame, camera_frame, tool_frame)


@dataclass
class HandEyeOutcome:
    """The joint estimate, its camera's assessment and the seconds it took."""

    result: HandEyeResult
    assessment: Assessment
    seconds: float

    def record(self, frames: HandEyeFrames) -> HandEyeRecord:
        """What HAND_EYE.yaml holds."""
        he = self.result
        return HandEyeRecord(mode=he.mode, parent_frame=frames.parent, child_frame=frames.camera, X=he.hand_eye,
                             translation_std_mm=_three(he.translation_std_mm),
                             rotation_std_deg=_three(he.rotation_std_deg), target_frame=frames.target,
                             target=he.target, views_used=int(he.views_used), rms_px=float(he.rms_px),
                             translation_std_intrinsics_mm=_three(he.intrinsics_share_mm),
                             rotation_std_intrinsics_deg=_three(he.intrinsics_share_deg))

    def camera_info(self, camera_name: str) -> CameraInfoData:
        """The CameraInfo data of the joint estimate's camera (:func:`~.outputs.camera_info_data`)."""
        return camera_info_data(self.assessment.result, camera_name)

    def write(self, paths: ResultPaths, camera_name: str, frames: HandEyeFrames,
              report: ReportRequest | None = None) -> WrittenFiles:
        """The result's files, ``hand_eye.yaml`` included (:func:`~.outputs.write_result_files`)."""
        return write_result_files(paths, self.assessment, camera_name, self.record(frames), report, self.result)

    def answer(self, frames: HandEyeFrames, n_views: int, hand_eye_yaml: str, camera_yaml: str) -> tuple[str, str]:
        """(the transform's line, the node's whole ``~/calibrate`` answer: that line and the camera's)."""
        line = hand_eye_line(self.result, frames.parent, frames.camera, n_views, hand_eye_yaml)
        return line, f"{line}; camera: {camera_answer(self.assessment, self.seconds, camera_yaml, self.warnings)}"

    @property
    def warnings(self) -> list[str]:
        """The camera's and the hand-eye estimate's warnings, each once."""
        return list(dict.fromkeys([*self.assessment.warnings, *self.result.warnings]))


def _three(v: np.ndarray) -> tuple[float, float, float]:
    a = np.asarray(v, float).ravel()
    return float(a[0]), float(a[1]), float(a[2])


def run_hand_eye(dets: list[Detection], robot_poses: Sequence[Transform | None], target: Target,
                 options: CalibrationOptions, he_options: HandEyeOptions, *, distance: float | None = None
                 ) -> HandEyeOutcome:
    """Intrinsics and the hand-eye transform in one estimate (:func:`~..calibrate.handeye.
    calibrate_hand_eye`), the camera assessed as an intrinsic calibration is.

    Raises
    ------
    CalibrationError
        (and its HandEyeError) when the views or the robot poses cannot give a result.
    """
    t0 = time.perf_counter()
    he = calibrate_hand_eye(dets, robot_poses, target, he_options.mode, options, he_options)
    return HandEyeOutcome(he, assess(he.calibration, distance), time.perf_counter() - t0)


def hand_eye_doubts(he: HandEyeResult) -> list[str]:
    """Why a hand-eye result must not be published (a transform or sigma that is not finite, sigma
    above :data:`MAX_HAND_EYE_STD_MM` / :data:`MAX_HAND_EYE_STD_DEG`); empty if it may."""
    problems = []
    X = he.hand_eye
    t_std = np.asarray(he.translation_std_mm, float)
    r_std = np.asarray(he.rotation_std_deg, float)
    if not (np.all(np.isfinite(X.translation)) and np.all(np.isfinite(X.quat))):
        problems.append("the transform is not finite")
    if not (np.all(np.isfinite(t_std)) and np.all(np.isfinite(r_std))):
        problems.append("its uncertainty is unknown (the robot motions do not determine it)")
    else:
        if t_std.max() > MAX_HAND_EYE_STD_MM:
            problems.append(f"translation std up to {t_std.max():.2f} mm (> {MAX_HAND_EYE_STD_MM:g} mm)")
        if r_std.max() > MAX_HAND_EYE_STD_DEG:
            problems.append(f"rotation std up to {r_std.max():.3f} deg (> {MAX_HAND_EYE_STD_DEG:g} deg)")
    return problems


def hand_eye_line(he: HandEyeResult, parent: str, camera_frame: str, n_views: int, yaml_path: str) -> str:
    """The node's answer for the transform: 'hand_eye <mode>: <parent> -> <camera> t=[..] m std=[..]
    mm (arm accuracy share [..] mm) q=[..] rot_std=[..] deg views_used=N/M rms= robot_error= yaml='."""
    X, q = he.hand_eye, he.hand_eye.quat
    return (f"hand_eye {he.mode}: {parent} -> {camera_frame} t=[{', '.join(f'{v:.5f}' for v in X.translation)}] m "
            f"std=[{', '.join(f'{v:.3f}' for v in he.translation_std_mm)}] mm "
            f"(arm accuracy share [{', '.join(f'{v:.3f}' for v in he.arm_share_mm)}] mm) "
            f"q=[{', '.join(f'{v:.6f}' for v in q)}] "
            f"rot_std=[{', '.join(f'{v:.4f}' for v in he.rotation_std_deg)}] deg "
            f"views_used={he.views_used}/{n_views} rms={he.rms_px:.3f}px "
            f"robot_error={he.robot_error_mm:.3f}mm/{he.robot_error_deg:.4f}deg yaml={yaml_path}")
