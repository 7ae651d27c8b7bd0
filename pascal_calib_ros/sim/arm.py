"""Simulated robot-arm sessions for hand-eye calibration, rendered with the exact renderer.

``eye_in_hand``: the camera rides on the tool (X = T_tool_camera) and looks at a target lying on
the table (Y = T_base_target). ``eye_to_hand``: the camera stands still (X = T_base_camera) and
the tool carries the target past it (Y = T_tool_target). The camera poses are drawn like a
calibration session (:func:`~.render.random_poses`: the whole target in view, tilted 15-45 degrees
about varied axes, rolled); the tool poses follow from the loop, G_i = Y C_i^-1 X^-1 (eye in hand)
or X C_i Y^-1 (eye to hand), and are then spoiled like a real arm's reading: a systematic error
and independent noise per pose and axis (``noise_mm``, ``noise_deg``; about the tool's own axes).

The systematic error is what a real arm's kinematic errors (link lengths, joint offsets) do: a
smooth error of the reported tool position that depends on where the tool is. It is modelled as
a field over the workspace, per base axis j: ``systematic_mm * sin(k_j . p + phi_j)`` (p the true
tool position; k_j of length 2 pi / ``systematic_wavelength``, random directions, phi_j random,
all drawn from the seed), so a few tenths of a millimetre that vary over the poses: part of it is
a constant offset (absorbed by the target's pose), part a gradient (a scale or shear of the arm's
motions that hand-eye cannot separate from X). Optionally also a scale error of the arm's
translations about the base origin (``scale_error``; off by default: 5e-4 is 0.6 mm at 1.2 m, more
than a few tenths, and not observable at all in eye to hand).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import Camera, ImageSize, Transform
from ..modes import HandEyeMode
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
    mode: HandEyeMode = HandEyeMode.EYE_IN_HAND
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
    systematic_mm: float = 0.25  # amplitude per base axis of the smooth position error field (systematic)
    systematic_wavelength: float = 1.0  # m, of the error field
    scale_error: float = 0.0  # the arm's translations scaled by 1 + this (systematic)
    blur: float = 1.0
    gamma: float = 2.2
    sensor_noise: float = 1.5
    size_range: tuple[float, float] = (0.35, 0.6)
    tilt_range: tuple[float, float] = (15.0, 45.0)
    # the seed of the systematic error field (None: ``seed``); one arm over several sessions keeps its field
    field_seed: int | None = None

    def camera(self) -> Camera:
        return SessionSpec(width=self.width, height=self.height, focal=self.focal, k1=self.k1, lens=self.lens,
                           dist=self.dist).camera()

    def __post_init__(self) -> None:
        object.__setattr__(self, "mode", HandEyeMode(self.mode))  # text given for the mode becomes the enum

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


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
    # a stream of its own: the poses do not depend on it
    field_rng = np.random.default_rng([spec.seed if spec.field_seed is None else spec.field_seed, 12])
    kdir = field_rng.normal(size=(3, 3))
    kvec = 2 * np.pi / spec.systematic_wavelength * kdir / np.linalg.norm(kdir, axis=1, keepdims=True)
    phase = field_rng.uniform(0, 2 * np.pi, 3)
    true, meas = [], []
    for p in poses:
        C = Transform.from_rt(p.R, p.t)
        G = Y @ C.inverse() @ X.inverse() if spec.mode == HandEyeMode.EYE_IN_HAND else X @ C @ Y.inverse()
        true.append(G)
        field_err = spec.systematic_mm / 1000 * np.sin(kvec @ G.translation + phase)
        g = Transform(G.rotation, G.translation * (1 + spec.scale_error) + field_err)
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
