"""Synthetic capture sessions: a camera, a set of poses, rendered views and ground truth."""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..calibrate import target_shape_frame
from ..geometry import Camera, ImageSize
from ..targets import Target
from .render import (
    Pose,
    RenderedView,
    SensorModel,
    SheetShape,
    look_at_pose,
    partial_poses,
    random_poses,
    render_view,
    write_view,
)


@dataclass(frozen=True)
class SessionSpec:
    width: int = 800
    height: int = 600
    focal: float = 0.0  # px; 0 -> image width
    k1: float = 0.0
    views: int = 12
    blur: float = 1.0
    gamma: float = 2.2
    noise: float = 1.5
    jpeg: int = 0
    seed: int = 0
    cut_views: int = 0
    empty_views: int = 0
    defocused_views: int = 0
    size_range: tuple[float, float] = (0.3, 0.6)
    tilt_range: tuple[float, float] = (15.0, 50.0)
    # the printed sheet (render.SheetShape): y/x pitch ratio - 1, parabolic warp in metres
    pitch_ratio: float = 0.0
    warp_x: float = 0.0
    warp_y: float = 0.0
    # the lens (a lens.MODELS name) and its coefficients; empty dist: plumb_bob from k1 below
    lens: str = "plumb_bob"
    dist: tuple[float, ...] = ()
    # where the target's centre is placed, as a fraction of the width and height
    pixel_range: tuple[float, float] = (0.2, 0.8)
    # views where a marker board hangs partly out of the frame (render.partial_poses), after the others
    partial_views: int = 0

    def sheet_shape(self, target: Target) -> SheetShape | None:
        """The sheet's shape over the frame of the target's features, or None if nominal."""
        if not (self.pitch_ratio or self.warp_x or self.warp_y):
            return None
        return SheetShape(self.pitch_ratio, self.warp_x, self.warp_y, target_shape_frame(target, (0.0, 0.0)))

    def camera(self) -> Camera:
        """Ground-truth camera: slightly non-square pixels, off-centre principal point; with k1,
        a plausible k2 and small tangential terms."""
        f = self.focal or float(self.width)
        cx, cy = self.width * 0.511, self.height * 0.491
        if self.dist or self.lens != "plumb_bob":
            return Camera.from_params(f, f * 1.0025, cx, cy, dist=list(self.dist) or None, width=self.width,
                                      height=self.height, model=self.lens)
        sgn = float(np.sign(self.k1))
        dist = [self.k1, -0.5 * self.k1 * abs(self.k1), 0.0008 * sgn, -0.0005 * sgn, 0.0]
        return Camera.from_params(f, f * 1.0025, cx, cy, dist=dist if self.k1 else None,
                                  width=self.width, height=self.height)

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def session_views(target: Target, spec: SessionSpec) -> list[tuple[str, Pose | None, SensorModel]]:
    """(name, pose, sensor) for every view of the session, extras last."""
    cam = spec.camera()
    rng = np.random.default_rng(spec.seed)
    poses = random_poses(target, cam, spec.views, rng, spec.tilt_range, spec.size_range,
                         pixel_range=spec.pixel_range)

    def sensor(k: int, blur: float | None = None) -> SensorModel:
        return SensorModel(blur_sigma=spec.blur if blur is None else blur, noise_sigma=spec.noise, gamma=spec.gamma,
                           jpeg_quality=spec.jpeg, seed=spec.seed * 1000 + k)

    out: list[tuple[str, Pose | None, SensorModel]] = [(f"view_{k:03d}", p, sensor(k)) for k, p in enumerate(poses)]
    k = len(out)
    for j in range(spec.cut_views):
        # target centre near a border so that part of it leaves the frame
        side = j % 4
        px = [(0.02, 0.5), (0.98, 0.5), (0.5, 0.03), (0.5, 0.97)][side]
        pose = look_at_pose(target, cam, (px[0] * cam.width, px[1] * cam.height), 0.5, 25.0, 90.0 * j, 10.0)
        out.append((f"cut_{j:03d}", pose, sensor(k)))
        k += 1
    for j, p in enumerate(partial_poses(target, cam, spec.partial_views, rng) if spec.partial_views else []):
        out.append((f"partial_{j:03d}", p, sensor(k)))
        k += 1
    for j in range(spec.empty_views):
        out.append((f"empty_{j:03d}", None, sensor(k)))
        k += 1
    for j in range(spec.defocused_views):
        p = random_poses(target, cam, 1, rng, spec.tilt_range, spec.size_range)[0]
        out.append((f"defocused_{j:03d}", p, sensor(k, blur=7.0)))
        k += 1
    return out


def render_session(target: Target, spec: SessionSpec, out_dir: Path, progress: bool = False) -> list[Path]:
    """Render every view to ``out_dir`` (PNG, or JPEG with ``spec.jpeg``) with ``.json`` ground
    truth beside each image and ``session.json`` for the whole session."""
    out_dir.mkdir(parents=True, exist_ok=True)
    cam = spec.camera()
    views = session_views(target, spec)
    ext = ".jpg" if spec.jpeg else ".png"
    paths = []
    for k, (name, pose, sens) in enumerate(views, 1):
        if progress:
            sys.stderr.write(f"\r[{k}/{len(views)}] rendering {name}")
            sys.stderr.flush()
        v = render_view(target, cam, pose, sens, spec.sheet_shape(target))
        v.meta["name"] = name
        paths.append(write_view(v, out_dir / f"{name}{ext}"))
    if progress:
        sys.stderr.write("\n")
    (out_dir / "session.json").write_text(json.dumps({
        "target": target.name, "spec": asdict(spec), "width": cam.width, "height": cam.height,
        "K": cam.K.tolist(), "D": cam.D.tolist(), "distortion_model": cam.model,
        "images": [p.name for p in paths]}, indent=1))
    return paths


def render_session_views(target: Target, spec: SessionSpec) -> tuple[Camera, list[RenderedView]]:
    """In-memory variant of :func:`render_session` (tests, studies)."""
    cam = spec.camera()
    views = []
    for name, pose, sens in session_views(target, spec):
        v = render_view(target, cam, pose, sens, spec.sheet_shape(target))
        v.meta["name"] = name
        views.append(v)
    return cam, views
