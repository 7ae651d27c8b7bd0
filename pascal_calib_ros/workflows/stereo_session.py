"""A live stereo session's calibration, ROS-free: what the node's stereo mode runs on ``~/calibrate``.

:func:`calibrate_stereo_session` is :func:`~.stereo.stereo_from_detections` (the CLI's ``pascal-calib
stereo`` on the same detections gives the same numbers) followed by the checks a published
calibration must pass (:func:`stereo_doubts`); only then are the files written
(:meth:`~.stereo.StereoOutcome.write`): ``left.yaml``, ``right.yaml``, ``stereo.yaml`` and each
camera's calibration record (``left.calibration.json``, ``right.calibration.json``: the covariance
``pascal-calib verify`` and ``export`` need), as the CLI writes them, and, when the frames were
kept, each camera's report and the pair's page (:func:`write_session_report`).

A recorded stereo session (:mod:`..io.session_folder`, a shot per view) is detected again as the
node stored it (:func:`recorded_stereo_shots`: what ``resume:=true`` stores before the first new
pair) and calibrated offline by :func:`run_recorded_stereo` (``pascal-calib stereo SESSION``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibrate import CalibrationOptions, RigOptions
from ..detect import Detection, DetectionParams, detect_target
from ..errors import PascalCalibError
from ..io import SessionFolder
from ..targets import Target
from .stereo import Pairing, StereoOptions, StereoOutcome, stereo_from_detections, write_reports

CAMERAS = ("left", "right")  # the cameras of a recorded stereo shot, in order

# a published rig transform must be known at least this well (the hand-eye node's limits)
MAX_SIGMA_DEG = 0.5
MAX_SIGMA_MM = 5.0
# a pair whose rectified rows disagree by more than this is not a calibration to publish (views of a
# target that moved between the two exposures, wrong pairs)
MAX_EPIPOLAR_RMS_PX = 1.0


class StereoSessionError(PascalCalibError):
    """The session's stereo calibration cannot be published; the message says why and what to do."""


@dataclass(frozen=True)
class StereoSessionOptions:
    """What the node's parameters set for a stereo calibration."""

    calibration: CalibrationOptions
    alpha: float = 0.0
    camera_name: str = "camera"
    left_frame: str = "left_camera_optical_frame"
    right_frame: str = "right_camera_optical_frame"

    def stereo(self) -> StereoOptions:
        return StereoOptions(RigOptions(calibration=self.calibration), self.alpha, self.camera_name,
                             self.left_frame, self.right_frame)


def stereo_output_dir(camera_name: str, output_dir: str = "") -> Path:
    """Where a stereo session's results go: ``output_dir``, else ``~/.ros/pascal_calib/<camera_name>/``
    (never the drivers' ``~/.ros/camera_info/``: their files change only through ``~/commit``)."""
    return Path(output_dir).expanduser() if output_dir else Path.home() / ".ros" / "pascal_calib" / camera_name


def stereo_doubts(outcome: StereoOutcome) -> list[str]:
    """Why the calibration cannot be stood behind (empty: it can): a non-finite value, a rig
    transform not known within :data:`MAX_SIGMA_DEG` / :data:`MAX_SIGMA_MM`, or an epipolar RMS
    above :data:`MAX_EPIPOLAR_RMS_PX`."""
    doubts = []
    infos = outcome.camera_infos()
    values = [np.ravel(a) for i in infos for a in (i.K, i.D, i.R, i.projection)]
    values.append(np.ravel(outcome.stereo.rig.matrix))
    if not all(np.all(np.isfinite(v)) for v in values):
        doubts.append("a parameter is not finite")
    sr, st = outcome.stereo.sigma_rotation_deg, outcome.stereo.sigma_translation_mm
    if not (np.all(np.isfinite(sr)) and np.all(np.isfinite(st))):
        doubts.append("the rig transform has no uncertainty (no covariance)")
    elif np.linalg.norm(sr) > MAX_SIGMA_DEG or np.linalg.norm(st) > MAX_SIGMA_MM:
        doubts.append(f"the rig transform is not determined well enough: sigma {np.linalg.norm(sr):.3f} deg, "
                      f"{np.linalg.norm(st):.2f} mm (limits {MAX_SIGMA_DEG} deg, {MAX_SIGMA_MM} mm); take more shots "
                      "both cameras see, tilted about different axes")
    if not np.isfinite(outcome.epipolar_rms) or outcome.epipolar_rms > MAX_EPIPOLAR_RMS_PX:
        doubts.append(f"epipolar RMS {outcome.epipolar_rms:.3f} px (limit {MAX_EPIPOLAR_RMS_PX} px): the two views "
                      "of a shot disagree, as when the target moved between the cameras' exposures; synchronise "
                      "the cameras or hold the target still")
    return doubts


def calibrate_stereo_session(dets: list[list[Detection]], target: Target, options: StereoSessionOptions
                             ) -> StereoOutcome:
    """The joint calibration of the session's shots (``dets[0]`` left, ``dets[1]`` right), checked;
    nothing written. Raises :class:`~..calibrate.result.CalibrationError` when it cannot be
    calibrated and :class:`StereoSessionError` when the result cannot be published."""
    outcome = stereo_from_detections(dets, target, options.stereo())
    doubts = stereo_doubts(outcome)
    if doubts:
        raise StereoSessionError("; ".join(doubts))
    return outcome


ShotImage = Callable[[int, str], "Path | None"]  # (camera, shot name) -> its stored frame, if kept


def write_session_report(outcome: StereoOutcome, dets: list[list[Detection]], target: Target, report_dir: str | Path,
                         frame_of: ShotImage) -> tuple[list[Path], str]:
    """Each camera's report and the pair's page in ``report_dir``, the images read through
    ``frame_of`` (the node's stored frames); returns the files and, when the report could not be
    written, why (a report never costs the calibration)."""
    names = [d.name for d in dets[0]]
    pairing = Pairing(names, [[frame_of(c, n) for n in names] for c in (0, 1)], "as stored by the node")
    try:
        return write_reports(outcome.rig, dets, pairing, report_dir, outcome, target), ""
    except Exception as e:  # a report must never cost the calibration
        return [], f"report not written: {type(e).__name__}: {e}"


def answer_line(outcome: StereoOutcome, files: list[Path]) -> str:
    """The ``~/calibrate`` answer: each camera's K and RMS, the rig transform with its sigma, the
    rectification's baseline, the epipolar RMS, the shots used, the files and the warnings."""
    rig, sd = outcome.rig, outcome.stereo
    cams = []
    for c, name in enumerate(rig.names):
        r = rig.cameras[c]
        K = r.K
        cams.append(f"{name}: fx={K[0, 0]:.2f} fy={K[1, 1]:.2f} cx={K[0, 2]:.2f} cy={K[1, 2]:.2f} rms={r.rms:.3f}px "
                    f"views={r.n_used}")
    t, sr, st = sd.rig.translation, sd.sigma_rotation_deg, sd.sigma_translation_mm
    both = int(np.sum(rig.used.sum(0) >= 2))
    parts = [*cams,
             f"X_right = R X_left + T: T=[{', '.join(f'{v:.5f}' for v in t)}] m "
             f"(+- [{', '.join(f'{v:.3f}' for v in st)}] mm), angle {sd.rig.angle_deg():.4f} deg "
             f"(+- [{', '.join(f'{v:.4f}' for v in sr)}] deg)",
             f"baseline {outcome.rectification.baseline:.5f} m, epipolar RMS {outcome.epipolar_rms:.3f} px",
             f"shots={both} both/{rig.used.shape[1]}"]
    if files:
        parts.append(f"yaml={files[0]}, {files[1].name}, {files[2].name}")
    parts += [f"warning: {w}" for w in rig.warnings]
    return "; ".join(parts)


def recorded_stereo_shots(folder: SessionFolder, target: Target, params: DetectionParams
                          ) -> list[tuple[Detection, Detection]]:
    """The shots of a recorded stereo session as the node stored them: each camera's frame detected
    again (named by its shot), a view the node did not use kept as a rejected detection with the
    recorded reason. Raises :class:`StereoSessionError` for a folder that is not a stereo session
    and :class:`~..io.session_folder.SessionFolderError` for a frame that cannot be read."""
    if folder.manifest.cameras != CAMERAS:
        raise StereoSessionError(f"{folder.path} is not a stereo session (its cameras: "
                                 f"{', '.join(folder.manifest.cameras) or 'one'}; left, right expected)")
    shots = []
    for view in list(folder.views):
        dets = []
        for c in (0, 1):
            img = folder.image(view, c)
            why = view.not_used[c] if view.not_used else ""
            dets.append(Detection(img.shape[1], img.shape[0], name=view.name, reason=why) if why
                        else detect_target(img, target, params, name=view.name))
        shots.append((dets[0], dets[1]))
    return shots


def recorded_pairing(folder: SessionFolder) -> Pairing:
    """Each camera's frame of each recorded shot (for the reports)."""
    views = list(folder.views)
    return Pairing([v.name for v in views], [[folder.path / v.images[c] for v in views] for c in (0, 1)],
                   f"as recorded in {folder.path}")


def run_recorded_stereo(folder: SessionFolder, target: Target, options: StereoOptions, params: DetectionParams,
                        out_dir: str | Path) -> tuple[Pairing, list[list[Detection]], StereoOutcome]:
    """A recorded stereo session calibrated offline (``pascal-calib stereo SESSION``): the shots the
    node stored (:func:`recorded_stereo_shots`) -> :func:`~.stereo.stereo_from_detections`, the
    files in ``out_dir``; the same numbers as the node's ``~/calibrate`` on those shots."""
    shots = recorded_stereo_shots(folder, target, params)
    dets = [[s[0] for s in shots], [s[1] for s in shots]]
    return recorded_pairing(folder), dets, stereo_from_detections(dets, target, options, out_dir)
