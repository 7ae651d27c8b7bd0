"""A recorded session: every stored view written as it is taken, so that nothing is lost when the
process dies (the role of easy_handeye2's ``save_samples`` and of ``camera_calibration``'s sample
tarball).

Layout::

    SESSION/
      session.yaml           # the manifest and the views, rewritten atomically after each view
      target.yaml            # a copy of the target file (when the target was given as a file)
      frames/<name>.png      # each stored frame (lossless), written before session.yaml names it

``session.yaml``::

    format: pascal_calib_session 1
    manifest: {target: ring_grid_a4, camera_name: camera, distortion_model: plumb_bob, gamma: 1.0,
               hand_eye: eye_in_hand, frame_id: base_link, child_frame_id: tool0, image_size: [1280, 960]}
    views:
      - {name: frame_000012, image: frames/frame_000012.png, stamp_ns: 1700000000000000000,
         translation: [x, y, z], rotation: [qx, qy, qz, qw]}     # the tool in the base (robot sessions)

A view exists once ``session.yaml`` names it (:mod:`.atomic`: the file is the old list or the new
one); a frame written just before a kill and never named is ignored and overwritten. ``~/reset``
keeps the cleared views as ``cleared-<time>.session.yaml`` beside their frames.
"""

from __future__ import annotations

import shutil
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import PascalCalibError
from ..geometry import Transform, TransformError
from .atomic import FileWriteError, write_bytes_atomic, write_text_atomic
from .images import ImageReadError, ImageWriteError, encode_image, read_grey

FORMAT = "pascal_calib_session 1"
SESSION_FILE = "session.yaml"
TARGET_COPY = "target.yaml"


class SessionFolderError(PascalCalibError):
    """A session folder that cannot be read, written or continued (the reason, with its path)."""


@dataclass(frozen=True)
class SessionManifest:
    """What a session was recorded with: enough to calibrate it again offline."""

    target: str  # as the node was given it (a packaged name or a path)
    camera_name: str = "camera"
    distortion_model: str = "plumb_bob"
    gamma: float = 1.0
    hand_eye: str = ""  # "", "eye_in_hand" or "eye_to_hand"
    frame_id: str = ""  # the robot base frame of the poses
    child_frame_id: str = ""  # the robot tool frame
    image_size: tuple[int, int] | None = None  # (width, height) of the frames

    def differences(self, other: SessionManifest) -> list[str]:
        """The fields (but the image size) on which ``other`` disagrees with this manifest, as
        ``name: this != other``."""
        keys = ("target", "camera_name", "distortion_model", "gamma", "hand_eye", "frame_id", "child_frame_id")
        return [f"{k}: {getattr(self, k)!r} != {getattr(other, k)!r}" for k in keys
                if getattr(self, k) != getattr(other, k)]


@dataclass(frozen=True)
class RecordedView:
    """One stored view: its name, its frame (relative to the folder), its stamp and robot pose."""

    name: str
    image: str
    stamp_ns: int
    robot_pose: Transform | None = None

    def document(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"name": self.name, "image": self.image, "stamp_ns": int(self.stamp_ns)}
        if self.robot_pose is not None:
            doc["translation"] = [float(x) for x in self.robot_pose.translation]
            doc["rotation"] = [float(x) for x in self.robot_pose.quat]
        return doc


def _view_of(doc: Any, where: str) -> RecordedView:
    if not isinstance(doc, dict) or not isinstance(doc.get("name"), str) or not isinstance(doc.get("image"), str):
        raise SessionFolderError(f"{where}: a view needs a name and an image")
    pose = None
    if "translation" in doc or "rotation" in doc:
        try:
            pose = Transform.from_quat(doc.get("rotation"), doc.get("translation"))
        except (TransformError, TypeError, ValueError) as e:
            raise SessionFolderError(f"{where}: view {doc['name']}: bad robot pose ({e})") from None
    return RecordedView(doc["name"], doc["image"], int(doc.get("stamp_ns", 0)), pose)


def _manifest_of(doc: Any, where: str) -> SessionManifest:
    if not isinstance(doc, dict) or not isinstance(doc.get("target"), str):
        raise SessionFolderError(f"{where}: the manifest needs a target")
    size = doc.get("image_size")
    fields = {k: doc[k] for k in ("camera_name", "distortion_model", "hand_eye", "frame_id", "child_frame_id")
              if isinstance(doc.get(k), str)}
    return SessionManifest(doc["target"], gamma=float(doc.get("gamma", 1.0)),
                           image_size=(int(size[0]), int(size[1])) if size else None, **fields)


def is_session_folder(path: str | Path) -> bool:
    """Whether ``path`` is a folder holding a ``session.yaml``."""
    return (Path(path) / SESSION_FILE).is_file()


class SessionFolder:
    """A session folder being recorded or read (module docstring); thread-safe."""

    def __init__(self, path: Path, manifest: SessionManifest, views: list[RecordedView]) -> None:
        self.path = path
        self.manifest = manifest
        self.views = views
        self._lock = threading.Lock()

    @classmethod
    def create(cls, path: str | Path, manifest: SessionManifest) -> SessionFolder:
        """A new session in ``path`` (created); refuses a folder that already holds views. A target
        given as a file is copied beside the views."""
        p = Path(path).expanduser()
        if is_session_folder(p) and cls.open(p).views:
            raise SessionFolderError(f"{p} already holds a session with views: continue it (resume) or choose "
                                     "another folder")
        src = Path(manifest.target).expanduser()
        try:
            p.mkdir(parents=True, exist_ok=True)
            if src.is_file():
                write_bytes_atomic(p / TARGET_COPY, src.read_bytes())
        except (OSError, FileWriteError) as e:
            raise SessionFolderError(f"cannot create the session folder {p}: {e}") from None
        folder = cls(p, manifest, [])
        folder._write()
        return folder

    @classmethod
    def open(cls, path: str | Path) -> SessionFolder:
        """An existing session folder (:class:`SessionFolderError` when it cannot be read)."""
        p = Path(path).expanduser()
        f = p / SESSION_FILE
        try:
            doc = yaml.safe_load(f.read_text())
        except (OSError, yaml.YAMLError) as e:
            raise SessionFolderError(f"{f}: cannot read ({e})") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise SessionFolderError(f"{f}: not a session file (format {FORMAT!r} expected)")
        views = [_view_of(v, str(f)) for v in doc.get("views") or []]
        return cls(p, _manifest_of(doc.get("manifest"), str(f)), views)

    def target_source(self) -> str:
        """The target to load: the copy in the folder when there is one, else the manifest's name."""
        copy = self.path / TARGET_COPY
        return str(copy) if copy.is_file() else self.manifest.target

    def record(self, name: str, image: np.ndarray, stamp_ns: int, robot_pose: Transform | None) -> RecordedView:
        """Write a stored view: its frame, then ``session.yaml`` naming it (both atomic).
        Raises :class:`SessionFolderError` with the reason; the view is then not recorded."""
        rel = f"frames/{name}.png"
        try:
            write_bytes_atomic(self.path / rel, encode_image(image, ".png"))
        except (FileWriteError, ImageWriteError) as e:
            raise SessionFolderError(str(e)) from None
        view = RecordedView(name, rel, int(stamp_ns), robot_pose)
        with self._lock:
            if self.manifest.image_size is None:
                self.manifest = replace(self.manifest, image_size=(int(image.shape[1]), int(image.shape[0])))
            self.views.append(view)
            try:
                self._write()
            except SessionFolderError:
                self.views.pop()
                raise
        return view

    def image(self, view: RecordedView) -> np.ndarray:
        """A recorded view's frame (:class:`SessionFolderError` when it cannot be read)."""
        try:
            return read_grey(self.path / view.image)
        except ImageReadError as e:
            raise SessionFolderError(f"view {view.name}: {e}") from None

    def clear(self) -> int:
        """Start over (``~/reset``): the views so far are kept as ``cleared-<time>.session.yaml``
        beside their frames; returns how many there were."""
        with self._lock:
            n = len(self.views)
            if n:
                stamp = time.strftime("%Y%m%d-%H%M%S")
                try:
                    shutil.copyfile(self.path / SESSION_FILE, self.path / f"cleared-{stamp}.{SESSION_FILE}")
                except OSError as e:
                    raise SessionFolderError(f"cannot keep the cleared views of {self.path}: {e}") from None
            self.views = []
            self._write()
        return n

    def _write(self) -> None:
        doc = {"format": FORMAT, "manifest": self._manifest_doc(), "views": [v.document() for v in self.views]}
        try:
            write_text_atomic(self.path / SESSION_FILE, yaml.safe_dump(doc, sort_keys=False,
                                                                       default_flow_style=None))
        except FileWriteError as e:
            raise SessionFolderError(str(e)) from None

    def _manifest_doc(self) -> dict[str, Any]:
        m = self.manifest
        return {"target": m.target, "camera_name": m.camera_name, "distortion_model": m.distortion_model,
                "gamma": float(m.gamma), "hand_eye": m.hand_eye, "frame_id": m.frame_id,
                "child_frame_id": m.child_frame_id, "image_size": list(m.image_size) if m.image_size else None}
