"""A recorded session: every stored view written as it is taken, so that nothing is lost when the
process dies (the role of easy_handeye2's ``save_samples`` and of ``camera_calibration``'s sample
tarball).

Layout::

    SESSION/
      session.yaml           # the manifest and the views, rewritten atomically after each view
      target.yaml            # a copy of the target file (when the target was given as a file)
      frames/<name>.png      # each stored frame (lossless), written before session.yaml names it
      frames/<camera>/<name>.png   # a shot of several cameras (a stereo pair): one frame per camera

``session.yaml``::

    format: pascal_calib_session 1
    manifest: {target: ring_grid_a4, camera_name: camera, distortion_model: plumb_bob, gamma: 1.0,
               hand_eye: eye_in_hand, frame_id: base_link, child_frame_id: tool0, image_size: [1280, 960]}
    views:
      - {name: frame_000012, image: frames/frame_000012.png, stamp_ns: 1700000000000000000,
         translation: [x, y, z], rotation: [qx, qy, qz, qw]}     # the tool in the base (robot sessions)

A session of several cameras (``manifest.cameras``, e.g. ``[left, right]``; ``frame_id`` and
``child_frame_id`` then hold the left and the right optical frame) records shots: one frame and
one stamp per camera, in the manifest's order, and why a camera's view was not used (empty: used)::

    views:
      - {name: shot_000004, images: [frames/left/shot_000004.png, frames/right/shot_000004.png],
         stamps_ns: [1700000000000000000, 1700000000001000000], not_used: ['', 'moving ...']}

A view exists once ``session.yaml`` names it (:mod:`.atomic`: the file is the old list or the new
one); a frame written just before a kill and never named is ignored and overwritten, a named one
never is (a name is recorded once). ``~/reset`` keeps the cleared views as
``cleared-<time>.session.yaml`` beside their frames.
"""

from __future__ import annotations

import shutil
import threading
import time
from collections.abc import Sequence
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
    frame_id: str = ""  # the robot base frame of the poses (a stereo pair: the left optical frame)
    child_frame_id: str = ""  # the robot tool frame (a stereo pair: the right optical frame)
    image_size: tuple[int, int] | None = None  # (width, height) of the (first camera's) frames
    cameras: tuple[str, ...] = ()  # the cameras of a shot (a stereo pair: left, right); empty: one camera

    def differences(self, other: SessionManifest) -> list[str]:
        """The fields (but the image size) on which ``other`` disagrees with this manifest, as
        ``name: this != other``."""
        keys = ("target", "camera_name", "distortion_model", "gamma", "hand_eye", "frame_id", "child_frame_id",
                "cameras")
        return [f"{k}: {getattr(self, k)!r} != {getattr(other, k)!r}" for k in keys
                if getattr(self, k) != getattr(other, k)]


@dataclass(frozen=True)
class RecordedView:
    """One stored view: its name, its frame (relative to the folder), its stamp and robot pose; a
    shot of several cameras also has every camera's frame and stamp (``image`` and ``stamp_ns``
    are the first camera's) and why a camera's view was not used (empty: used)."""

    name: str
    image: str
    stamp_ns: int
    robot_pose: Transform | None = None
    images: tuple[str, ...] = ()
    stamps_ns: tuple[int, ...] = ()
    not_used: tuple[str, ...] = ()

    def document(self) -> dict[str, Any]:
        if self.images:
            shot: dict[str, Any] = {"name": self.name, "images": list(self.images),
                                    "stamps_ns": [int(t) for t in self.stamps_ns]}
            if any(self.not_used):
                shot["not_used"] = list(self.not_used)
            return shot
        doc: dict[str, Any] = {"name": self.name, "image": self.image, "stamp_ns": int(self.stamp_ns)}
        if self.robot_pose is not None:
            doc["translation"] = [float(x) for x in self.robot_pose.translation]
            doc["rotation"] = [float(x) for x in self.robot_pose.quat]
        return doc


def _shot_of(doc: dict[str, Any], where: str) -> RecordedView:
    images, stamps, not_used = doc["images"], doc.get("stamps_ns") or [], doc.get("not_used") or []
    if not isinstance(images, list) or not images or not all(isinstance(i, str) for i in images) or (
            len(stamps) != len(images) or len(not_used) not in (0, len(images))):
        raise SessionFolderError(f"{where}: shot {doc['name']}: needs one image and one stamp per camera")
    return RecordedView(doc["name"], images[0], int(stamps[0]), None, tuple(images), tuple(int(t) for t in stamps),
                        tuple(str(w) for w in not_used) or ("",) * len(images))


def _view_of(doc: Any, where: str) -> RecordedView:
    if isinstance(doc, dict) and isinstance(doc.get("name"), str) and "images" in doc:
        return _shot_of(doc, where)
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
                           image_size=(int(size[0]), int(size[1])) if size else None,
                           cameras=tuple(str(c) for c in doc.get("cameras") or ()), **fields)


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
        self._write_frames(name, [rel], [image])
        return self._append(RecordedView(name, rel, int(stamp_ns), robot_pose), image)

    def record_shot(self, name: str, images: Sequence[np.ndarray], stamps_ns: Sequence[int],
                    not_used: Sequence[str] = ()) -> RecordedView:
        """Write a stored shot of the manifest's cameras: each camera's frame, then ``session.yaml``
        naming the shot (all atomic); ``not_used[c]`` says why camera c's view was not used (empty:
        used). Raises :class:`SessionFolderError` with the reason; the shot is then not recorded."""
        cams = self.manifest.cameras
        if not cams or len(images) != len(cams) or len(stamps_ns) != len(cams) or len(not_used) not in (0, len(cams)):
            raise SessionFolderError(f"a shot of {self.path} needs one frame and one stamp for each of its cameras "
                                     f"({', '.join(cams) or 'none recorded'})")
        rels = [f"frames/{c}/{name}.png" for c in cams]
        self._write_frames(name, rels, images)
        view = RecordedView(name, rels[0], int(stamps_ns[0]), None, tuple(rels), tuple(int(t) for t in stamps_ns),
                            tuple(str(w) for w in not_used) or ("",) * len(cams))
        return self._append(view, images[0])

    def _write_frames(self, name: str, rels: list[str], images: Sequence[np.ndarray]) -> None:
        with self._lock:
            if any(v.name == name for v in self.views):  # a recorded frame is never overwritten
                raise SessionFolderError(f"{self.path} already records a view named {name}")
        try:
            for rel, image in zip(rels, images, strict=True):
                write_bytes_atomic(self.path / rel, encode_image(image, ".png"))
        except (FileWriteError, ImageWriteError) as e:
            raise SessionFolderError(str(e)) from None

    def _append(self, view: RecordedView, first: np.ndarray) -> RecordedView:
        with self._lock:
            if self.manifest.image_size is None:
                self.manifest = replace(self.manifest, image_size=(int(first.shape[1]), int(first.shape[0])))
            self.views.append(view)
            try:
                self._write()
            except SessionFolderError:
                self.views.pop()
                raise
        return view

    def image(self, view: RecordedView, camera: int = 0) -> np.ndarray:
        """A recorded view's frame (a shot: camera ``camera``'s; :class:`SessionFolderError` when it
        cannot be read)."""
        rel = view.images[camera] if view.images else view.image
        try:
            return read_grey(self.path / rel)
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
                "child_frame_id": m.child_frame_id, "image_size": list(m.image_size) if m.image_size else None,
                **({"cameras": list(m.cameras)} if m.cameras else {})}
