"""Rendered camera rigs: N cameras with known intrinsics, lens models and poses in camera 0's
frame, all looking at the same target poses (shots), with ground truth.

A rig camera's pose is given as its place in camera 0's frame, ``T_0c`` (p_cam0 = T_0c p_camc,
the :class:`~..geometry.transform.Transform` convention); the view of shot s by camera c is the
target -> camera c transform T_0c^-1 S_s, with S_s the shot's target -> camera 0 pose. A shot is
placed for one anchor camera (as :func:`~.render.random_poses` places single-camera views) and
kept as a *shared* shot when at least two cameras see the whole target, as a *single* shot when
exactly one does (those serve that camera's intrinsics only). Every camera renders every shot:
where the target is cut by the frame, the detector rejects the view, as it would a real one.

Files (:func:`write_rig`): ``OUT/<camera>/<shot>.png`` with ``<shot>.json`` beside each image
(the single-camera sessions' ground truth) and ``OUT/rig.json``: every camera's K, D, lens model,
size and pose in camera 0's frame, every shot's pose, which cameras see it whole.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry import Camera, Transform
from ..targets import Target
from .render import Pose, RenderedView, SensorModel, features_in_image, look_at_pose, render_view, write_view
from .session import SessionSpec


@dataclass(frozen=True)
class RigCamera:
    """One camera of a rendered rig: its name, the true camera and its pose in camera 0's frame."""

    name: str
    camera: Camera
    pose: Transform = field(default_factory=Transform.identity)  # p_cam0 = pose.apply(p_cam)


@dataclass(frozen=True)
class RigSpec:
    """A rig and how its shots are placed and imaged (sensor as :class:`~.session.SessionSpec`)."""

    cameras: tuple[RigCamera, ...]
    shots: int = 12  # shots at least two cameras see whole
    single_shots: int = 2  # shots exactly one camera sees whole (cycling through the cameras)
    seed: int = 0
    size_range: tuple[float, float] = (0.3, 0.6)
    tilt_range: tuple[float, float] = (15.0, 50.0)
    pixel_range: tuple[float, float] = (0.2, 0.8)
    blur: float = 1.0
    gamma: float = 2.2
    noise: float = 1.5
    jpeg: int = 0

    def sensor(self, camera: int, shot: int) -> SensorModel:
        """The sensor of one image (its own noise seed)."""
        return SensorModel(blur_sigma=self.blur, noise_sigma=self.noise, gamma=self.gamma, jpeg_quality=self.jpeg,
                           seed=self.seed * 100_000 + 1000 * camera + shot)


def stereo_pair(width: int = 800, height: int = 600, k1: float = -0.2, baseline: float = 0.12,
                angle_deg: float = 2.0, lens: str = "plumb_bob", focal: float = 0.0,
                dist: tuple[float, ...] = ()) -> tuple[RigCamera, RigCamera]:
    """A horizontal stereo head: the right camera ``baseline`` metres to the right of the left
    one (and 1.5 mm down, 1 mm back), turned by ``angle_deg`` in all, mostly toe-in about y,
    with intrinsics and distortion a little different from the left's (as two real cameras of one
    model). ``lens``/``focal``/``dist`` as :class:`~.session.SessionSpec`'s."""
    base = SessionSpec(width=width, height=height, k1=k1, lens=lens, focal=focal, dist=dist)
    left = base.camera()
    K = left.K.copy()
    K[0, 0] *= 1.004
    K[1, 1] *= 1.0035
    K[0, 2], K[1, 2] = width * 0.494, height * 0.507
    D = left.D.copy()
    if lens == "equidistant":
        D = D * np.array([1.05, 0.9, 1.0, 1.0])[: len(D)]
    elif len(D):
        D[0] *= 0.92
        D[2:4] = -D[2:4]
    right = Camera(K, D, width, height, left.model)
    axis = np.array([0.15, -0.98, 0.12])
    rot = Rotation.from_rotvec(np.radians(angle_deg) * axis / np.linalg.norm(axis))
    pose = Transform(rot, np.array([baseline, 0.0015, -0.001]))
    return RigCamera("left", left), RigCamera("right", right, pose)


@dataclass
class RigSession:
    """A rendered rig: per camera and shot the image (None when not rendered), the shot poses
    (target -> camera 0) and which cameras see each shot whole."""

    spec: RigSpec
    target: str
    shot_poses: list[Transform]
    names: list[str]  # shot names (file stems)
    seen: np.ndarray  # (cameras, shots) bool: the whole target in view
    images: list[list[np.ndarray]] = field(default_factory=list)  # [camera][shot]

    def view_pose(self, camera: int, shot: int) -> Transform:
        """Target -> camera ``camera`` at ``shot``."""
        return self.spec.cameras[camera].pose.inverse() @ self.shot_poses[shot]

    def extrinsic(self, camera: int) -> Transform:
        """Camera 0's frame -> camera ``camera``'s (X_c = R X_0 + t; a stereo pair's R, T)."""
        return self.spec.cameras[camera].pose.inverse()


def _to_pose(T: Transform) -> Pose:
    return Pose(T.R, T.translation.copy())


def _visible(target: Target, spec: RigSpec, shot: Transform) -> np.ndarray:
    out = []
    for rc in spec.cameras:
        view = rc.pose.inverse() @ shot
        out.append(features_in_image(target, rc.camera, _to_pose(view), margin=10.0))
    return np.array(out, bool)


def rig_shots(target: Target, spec: RigSpec, max_tries: int = 20_000) -> tuple[list[Transform], np.ndarray]:
    """The shot poses (target -> camera 0) and the (cameras, shots) visibility: ``spec.shots``
    shared shots, then ``spec.single_shots`` seen whole by one camera only (the anchor cycles
    through the cameras)."""
    rng = np.random.default_rng(spec.seed)
    n_cam = len(spec.cameras)
    shots: list[Transform] = []
    seen: list[np.ndarray] = []
    for want_single, count in ((False, spec.shots), (True, spec.single_shots)):
        made, tries = 0, 0
        while made < count:
            tries += 1
            if tries > max_tries:
                kind = "seen by one camera only" if want_single else "shared by two cameras"
                raise RuntimeError(f"could not place {count} shots {kind}; widen the ranges or move the cameras")
            anchor = spec.cameras[made % n_cam]
            lo, hi = (0.03, 0.97) if want_single else spec.pixel_range
            pixel = (rng.uniform(lo, hi) * anchor.camera.width, rng.uniform(lo, hi) * anchor.camera.height)
            p = look_at_pose(target, anchor.camera, pixel, rng.uniform(*spec.size_range), rng.uniform(*spec.tilt_range),
                             rng.uniform(0, 360), rng.uniform(-30, 30))
            shot = anchor.pose @ Transform.from_rt(p.R, p.t)
            vis = _visible(target, spec, shot)
            if (vis.sum() == 1) if want_single else (vis.sum() >= 2):
                shots.append(shot)
                seen.append(vis)
                made += 1
    return shots, np.array(seen, bool).T.reshape(n_cam, len(shots))


def render_rig(target: Target, spec: RigSpec) -> RigSession:
    """Every camera's image of every shot (in memory)."""
    shots, seen = rig_shots(target, spec)
    names = [f"shot_{k:03d}" for k in range(spec.shots)] + \
        [f"single_{k:03d}" for k in range(spec.single_shots)]
    session = RigSession(spec, target.name, shots, names, seen)
    for c, rc in enumerate(spec.cameras):
        session.images.append([render_view(target, rc.camera, _to_pose(session.view_pose(c, s)),
                                           spec.sensor(c, s)).image for s in range(len(shots))])
    return session


def rig_truth(session: RigSession) -> dict[str, object]:
    """The ground truth of a rendered rig as plain data (``rig.json``)."""
    cams = []
    for rc in session.spec.cameras:
        cams.append({"name": rc.name, "width": rc.camera.width, "height": rc.camera.height, "K": rc.camera.K.tolist(),
                     "D": rc.camera.D.tolist(), "distortion_model": rc.camera.model,
                     "pose_in_camera0": {"translation": rc.pose.translation.tolist(),
                                         "quaternion_xyzw": rc.pose.quat.tolist()}})
    return {"target": session.target, "cameras": cams,
            "shots": [{"name": n, "pose": {"rvec": T.rotvec.tolist(), "t": T.translation.tolist()},
                       "seen_by": [rc.name for c, rc in enumerate(session.spec.cameras) if session.seen[c, s]]}
                      for s, (n, T) in enumerate(zip(session.names, session.shot_poses, strict=True))]}


def write_rig(session: RigSession, out_dir: str | Path) -> list[list[Path]]:
    """``OUT/<camera>/<shot>.png`` (+ ``.json`` ground truth per image) and ``OUT/rig.json``."""
    out = Path(out_dir)
    paths: list[list[Path]] = []
    for c, rc in enumerate(session.spec.cameras):
        cam_paths = []
        for s, name in enumerate(session.names):
            view = render_view_meta(session, c, s)
            cam_paths.append(write_view(view, out / rc.name / f"{name}.png"))
        paths.append(cam_paths)
    (out / "rig.json").write_text(json.dumps(rig_truth(session), indent=1))
    return paths


def render_view_meta(session: RigSession, camera: int, shot: int) -> RenderedView:
    """The rendered view of (camera, shot) with its image and ground truth (for :func:`write_view`)."""
    rc = session.spec.cameras[camera]
    view = RenderedView(session.images[camera][shot], rc.camera, _to_pose(session.view_pose(camera, shot)),
                        session.spec.sensor(camera, shot), session.target)
    view.meta.update(name=session.names[shot], rig_camera=rc.name, seen_whole=bool(session.seen[camera, shot]))
    return view

