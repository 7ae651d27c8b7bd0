"""Simulated robot-arm sessions for hand-eye calibration, rendered with the exact renderer.

``eye_in_hand``: the camera rides on the tool (X = T_tool_camera) and looks at a target lying on
the table (Y = T_base_target). ``eye_to_hand``: the camera stands still (X = T_base_camera) and
the tool carries the target past it (Y = T_tool_target). The camera poses are drawn like a
calibration session (:func:`~.render.random_poses`: the whole target in view, tilted 15-45 degrees
about varied axes, rolled); the tool poses follow from the loop, G_i = Y C_i^-1 X^-1 (eye in hand)
or X C_i Y^-1 (eye to hand), and are then spoiled like a real arm's reading: a systematic error
(the arm's translations scaled by 1 + ``scale_error`` about the base origin: 5e-4 is 0.3 mm at
0.6 m reach) and independent noise per pose and axis (``noise_mm``, ``noise_deg``; about the
tool's own axes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.camera import Camera
from ..geometry.transform import Transform
from ..targets import Target
from .render import Pose, SensorModel, random_poses, render_view
from .session import SessionSpec

DEFAULT_HAND_EYE = {
    # camera 70 mm out along the flange's axis, 40 mm to the side, looking roughly along it
    "eye_in_hand": Transform.from_rotvec([0.03, -0.05, 1.3], [0.040, -0.025, 0.070]),
    # camera on a stand 1 m from the base, looking back at the workspace
    "eye_to_hand": Transform.from_rotvec([-2.0, 0.9, -0.4], [1.05, 0.35, 0.55]),
}
DEFAULT_TARGET = {
    # the sheet face up on the table (its z, into the sheet, points down), yawed
    "eye_in_hand": Transform.from_rotvec([np.pi, 0.0, 0.0], [0.55, 0.05, 0.02]) @ Transform.from_rotvec([0, 0, 0.4]),
    # the sheet screwed to a plate 60 mm out from the flange
    "eye_to_hand": Transform.from_rotvec([0.05, 0.1, 0.3], [-0.12, 0.09, 0.06]),
}


@dataclass(frozen=True)
class ArmSpec:
    mode: str = "eye_in_hand"
    views: int = 20
    width: int = 800
    height: int = 600
    focal: float = 0.0  # px; 0 -> the image width
    k1: float = 0.0
    lens: str = "plumb_bob"
    dist: tuple[float, ...] = ()
    seed: int = 0
    noise_mm: float = 0.1  # per axis and pose
    noise_deg: float = 0.01
    scale_error: float = 5e-4  # the arm's translations scaled by 1 + this (systematic)
    blur: float = 1.0
    gamma: float = 2.2
    sensor_noise: float = 1.5
    size_range: tuple[float, float] = (0.35, 0.6)
    tilt_range: tuple[float, float] = (15.0, 45.0)

    def camera(self) -> Camera:
        return SessionSpec(width=self.width, height=self.height, focal=self.focal, k1=self.k1, lens=self.lens,
                           dist=self.dist).camera()


@dataclass
class ArmSession:
    spec: ArmSpec
    camera: Camera  # ground truth
    hand_eye: Transform  # true X
    target_pose: Transform  # true Y (target YAML frame -> base, or -> tool)
    camera_poses: list[Pose]  # true target -> camera per view
    robot_poses_true: list[Transform]  # T_base_tool
    robot_poses: list[Transform]  # as the arm reports them (systematic error + noise)
    names: list[str] = field(default_factory=list)
    images: dict[str, list[np.ndarray]] = field(default_factory=dict)  # target name -> images


def arm_poses(spec: ArmSpec, pose_target: Target, hand_eye: Transform | None = None,
              target_pose: Transform | None = None) -> ArmSession:
    """The session's geometry (no images): camera poses that keep ``pose_target`` in view, the
    true and the measured robot poses."""
    if spec.mode not in DEFAULT_HAND_EYE:
        raise ValueError(f"unknown mode {spec.mode!r}")
    X = hand_eye or DEFAULT_HAND_EYE[spec.mode]
    Y = target_pose or DEFAULT_TARGET[spec.mode]
    cam = spec.camera()
    rng = np.random.default_rng(spec.seed)
    poses = random_poses(pose_target, cam, spec.views, rng, spec.tilt_range, spec.size_range)
    true, meas = [], []
    for p in poses:
        C = Transform.from_rt(p.R, p.t)
        G = Y @ C.inverse() @ X.inverse() if spec.mode == "eye_in_hand" else X @ C @ Y.inverse()
        true.append(G)
        g = Transform(G.rotation, G.translation * (1 + spec.scale_error))
        noise = Transform.from_rotvec(rng.normal(0, np.radians(spec.noise_deg), 3),
                                      rng.normal(0, spec.noise_mm / 1000, 3))
        meas.append(g @ noise)
    return ArmSession(spec, cam, X, Y, poses, true, meas, [f"view_{k:02d}.png" for k in range(len(poses))])


def render_arm_images(session: ArmSession, target: Target) -> list[np.ndarray]:
    """Images of ``target`` (the same sheet frame) at the session's camera poses; stored in
    ``session.images[target.name]``."""
    s = session.spec
    imgs = [render_view(target, session.camera, p, SensorModel(blur_sigma=s.blur, noise_sigma=s.sensor_noise,
                                                               gamma=s.gamma, seed=s.seed * 1000 + k)).image
            for k, p in enumerate(session.camera_poses)]
    session.images[target.name] = imgs
    return imgs


def simulate_arm_session(target: Target, spec: ArmSpec = ArmSpec(), pose_target: Target | None = None
                         ) -> ArmSession:
    """A rendered arm session of ``target`` (poses chosen to keep ``pose_target``, default the same
    target, in view: pass the largest of several targets to render them all from one set)."""
    session = arm_poses(spec, pose_target or target)
    render_arm_images(session, target)
    return session


def hand_eye_errors(X_est: Transform, X_true: Transform) -> tuple[float, float, np.ndarray, np.ndarray]:
    """(translation error mm, rotation error deg, per-axis translation error mm (parent axes),
    per-axis small-rotation error deg (parent axes))."""
    dt = 1000 * (X_est.translation - X_true.translation)
    dr = np.degrees((X_est.rotation * X_true.rotation.inv()).as_rotvec())
    return float(np.linalg.norm(dt)), float(np.linalg.norm(dr)), dt, dr
