"""Rendered rigs shared by the rig and stereo tests (rendered and calibrated once per test run)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.rig.calibration import RigOptions, RigResult, calibrate_rig
from pascal_calib_ros.detect.detection import Detection, DetectionParams
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.sim.rig import RigSession, RigSpec, render_rig, stereo_pair
from pascal_calib_ros.targets import resolve_target

GRID = "ring_grid_a4"
# a stereo head at 640x480: baseline 12 cm, 2 degrees between the cameras, k1 -0.2; 10 shots both
# see whole, 2 that one camera sees whole (the other sees part of the grid, or nothing)
PAIR_SPEC = RigSpec(stereo_pair(640, 480), shots=10, single_shots=2, seed=1)
# an equidistant fisheye pair of about 190 degrees across (f = 190 px at 640x480)
FISHEYE_SPEC = RigSpec(stereo_pair(640, 480, lens="equidistant", focal=190, dist=(0.02, -0.005, 0.001, -0.0002)),
                       shots=8, single_shots=0, seed=3, pixel_range=(0.05, 0.95), size_range=(0.35, 0.55))


@cache
def rendered(which: str) -> RigSession:
    return render_rig(resolve_target(GRID), PAIR_SPEC if which == "pair" else FISHEYE_SPEC)


@cache
def detections(which: str) -> tuple[tuple[Detection, ...], ...]:
    s = rendered(which)
    params = DetectionParams.for_lens(which == "fisheye", gamma=2.2)  # the renders' display gamma
    grid = resolve_target(GRID)
    return tuple(tuple(detect_target(im, grid, params, name=n) for im, n in zip(ims, s.names, strict=True))
                 for ims in s.images)


def det_lists(which: str) -> list[list[Detection]]:
    return [list(d) for d in detections(which)]


@cache
def calibrated(which: str) -> RigResult:
    opts = RigOptions(CalibrationOptions(distortion="equidistant" if which == "fisheye" else "plumb_bob"))
    return calibrate_rig(det_lists(which), resolve_target(GRID), ["left", "right"], opts)


def rotation_error_deg(est: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Per-axis small-rotation error (deg) of rotation matrices est against true (est = exp(e) true)."""
    from scipy.spatial.transform import Rotation

    return np.degrees((Rotation.from_matrix(est) * Rotation.from_matrix(true).inv()).as_rotvec())


def three_camera_spec() -> RigSpec:
    """Three cameras in a row, 15 cm apart, each turned 12 degrees further right: the outer two
    share no shot (they are connected through the middle one)."""
    from scipy.spatial.transform import Rotation

    from pascal_calib_ros.geometry.transform import Transform
    from pascal_calib_ros.sim.rig import RigCamera
    from pascal_calib_ros.sim.session import SessionSpec

    cam = SessionSpec(width=640, height=480, k1=-0.1).camera()
    turn = [Transform(Rotation.from_rotvec([0.0, np.radians(12 * k), 0.0]), [0.15 * k, 0.0, 0.015 * k * k])
            for k in range(3)]
    return RigSpec(tuple(RigCamera(n, cam, T) for n, T in zip("abc", turn, strict=True)), shots=12, single_shots=0,
                   seed=2, size_range=(0.35, 0.6))


@cache
def rendered_three() -> RigSession:
    return render_rig(resolve_target(GRID), three_camera_spec())


def write_rig_file(folder: Path, sigma_deg: float = 0.01) -> Path:
    """A ``rig.yaml`` of three cameras (cam1, cam2 0.1 m and 0.2 m right of cam0, turned 0.05 rad per
    step), each with a rotation sigma of ``sigma_deg``."""
    from pascal_calib_ros.geometry.transform import Transform
    from pascal_calib_ros.io.stereo_yaml import RigCameraData, write_rig_yaml

    cams = [RigCameraData("cam0", "cam0_optical_frame", "cam0.yaml", Transform(), np.zeros(3), np.zeros(3))]
    cams += [RigCameraData(f"cam{k}", f"cam{k}_optical_frame", f"cam{k}.yaml",
                           Transform.from_rotvec([0.0, 0.05 * k, 0.0], [0.1 * k, 0.0, 0.0]),
                           np.full(3, sigma_deg), np.full(3, 0.05)) for k in (1, 2)]
    return write_rig_yaml(folder / "rig.yaml", cams, 20)
