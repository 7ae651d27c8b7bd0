"""The calibration node's session folder and result sets: every stored view written as it is taken
(:mod:`..io.session_folder`), a session continued after a crash (``resume:=true``), and each
result written as one set and labelled (:mod:`..workflows.result_set`,
:mod:`..session.result_history`).

One mechanism for every mode: :class:`SessionRecording` opens, creates or resumes the folder,
counts what could not be written and starts over on ``~/reset``; :class:`NodeSession` is the mono
node's (a view per frame, with its robot pose), :class:`StereoNodeSession` the stereo mode's (a
shot of both cameras per view)."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from ..detect import detect_target
from ..geometry import Transform
from ..io import FileWriteError, SessionFolder, SessionFolderError, SessionManifest, is_session_folder, sidecar_path
from ..session import NOT_WRITTEN, SIDES, LiveSession, ResultHistory, StereoSession
from ..targets import Target
from ..workflows import (
    ResultSet,
    ResultStore,
    copy_atomic,
    detection_params,
    output_folder,
    recorded_stereo_shots,
)
from .node_parts import NodeCore
from .params import ParameterError

if TYPE_CHECKING:
    import numpy as np

    from ..detect import Detection

SESSIONS = "sessions"
_NUMBER = re.compile(r"(\d+)$")


class RecordedNode(NodeCore, Protocol):
    """What the mono node's recording uses of the node (:class:`.calibration_node.CalibrationNode`):
    the robot pose topic, the target, the live session a recorded view is stored in again, the labels."""

    pose_topic: str
    target: Target
    session: LiveSession
    history: ResultHistory


class RecordedStereoNode(NodeCore, Protocol):
    """What the stereo node's recording uses of the node (:class:`.stereo_node.StereoCalibrationNode`)."""

    target: Target
    session: StereoSession


N = TypeVar("N", bound=NodeCore)  # the node a recording belongs to, as the recording uses it


def manifest_of(node: RecordedNode) -> SessionManifest:
    """What the node records a session with (its parameters)."""
    p = node.p
    return SessionManifest(str(p("target")), str(p("camera_name")), str(p("distortion_model")), float(p("gamma")),
                           str(p("hand_eye")), str(p("robot_base_frame")) if node.pose_topic else "",
                           str(p("robot_tool_frame")) if node.pose_topic else "")


def recording_on(node: NodeCore) -> bool:
    """``record_session``: ``always``, ``never``, or ``auto`` (with ``collect:=on_capture`` or ``output_dir``)."""
    mode = str(node.p("record_session"))
    if mode == "auto":
        return str(node.p("collect")) == "on_capture" or bool(node.p("output_dir")) or bool(node.p("resume"))
    return mode == "always"


def newest_session(sessions: Path) -> Path | None:
    """The newest session folder under ``sessions`` (by name: they are named by time)."""
    found = sorted(p for p in sessions.glob("*") if is_session_folder(p)) if sessions.is_dir() else []
    return found[-1] if found else None


class SessionRecording(Generic[N]):
    """A node's session folder (None when not recording): opened, created or resumed at start,
    what could not be written counted; a mode says what it records (:meth:`manifest`), when
    (:meth:`recording_on`) and how a recorded view is stored again (:meth:`restore`)."""

    def __init__(self, node: N) -> None:
        self.node = node
        self.folder: SessionFolder | None = None
        self.not_written = 0
        self.last_error = ""
        self.name_offset = 0  # resumed views keep their names; new frames are numbered after them
        if self.recording_on():
            self.folder = self._open()

    def manifest(self) -> SessionManifest:
        """What the node records a session with (its parameters)."""
        raise NotImplementedError

    def recording_on(self) -> bool:
        """Whether the node records a session (``record_session``)."""
        raise NotImplementedError

    def restore(self, folder: SessionFolder) -> None:
        """Detect the folder's views again and store them in the live session."""
        raise NotImplementedError

    def base(self) -> Path:
        return output_folder(str(self.node.p("camera_name")), str(self.node.p("output_dir")))

    def _open(self) -> SessionFolder:
        node, manifest = self.node, self.manifest()
        given = str(node.p("session_dir"))
        try:
            if node.p("resume"):
                path = Path(given) if given else newest_session(self.base() / SESSIONS)
                if path is None or not is_session_folder(path):
                    raise ParameterError(f"resume:=true but there is no session to continue "
                                         f"({given or self.base() / SESSIONS}): start without resume")
                folder = SessionFolder.open(path)
                diff = folder.manifest.differences(manifest)
                if diff:
                    raise ParameterError(f"cannot resume {path}: it was recorded with other settings ("
                                         + "; ".join(diff) + "): start with the session's settings")
                return folder
            path = Path(given) if given else self.base() / SESSIONS / time.strftime("%Y%m%d-%H%M%S")
            return SessionFolder.create(path, manifest)
        except SessionFolderError as e:
            raise ParameterError(str(e)) from None

    def resume(self) -> int:
        """Detect the folder's views again and store them in the live session (:meth:`restore`);
        returns how many. New views are numbered after them (:attr:`name_offset`)."""
        if self.folder is None or not self.node.p("resume"):
            return 0
        try:
            self.restore(self.folder)
        except SessionFolderError as e:
            raise ParameterError(f"cannot resume {self.folder.path}: {e}") from None
        for view in self.folder.views:
            m = _NUMBER.search(view.name)
            if m:
                self.name_offset = max(self.name_offset, int(m.group(1)) + 1)
        return len(self.folder.views)

    def failed(self, e: SessionFolderError) -> str:
        """Count and log a view that could not be written; the answer's note."""
        self.not_written += 1
        self.last_error = f"{NOT_WRITTEN} to the session folder: {e}"
        self.node.get_logger().error(self.last_error, throttle_duration_sec=5.0)
        return self.last_error

    def clear(self) -> str:
        """``~/reset``: the folder starts over (the cleared views are kept); what happened."""
        if self.folder is None:
            return ""
        try:
            n = self.folder.clear()
        except SessionFolderError as e:
            return f"; the session folder could not start over: {e}"
        return f"; {n} recorded view(s) kept in {self.folder.path} (cleared-*.session.yaml)" if n else ""

    def folder_status(self) -> dict[str, Any]:
        """The folder's keys of ``~/status``."""
        out: dict[str, Any] = {"session_folder": str(self.folder.path) if self.folder is not None
                               else "(not recording)"}
        if self.folder is not None:
            out["session_views_written"] = len(self.folder.views)
            out["session_views_not_written"] = self.not_written
        return out


class NodeSession(SessionRecording[RecordedNode]):
    """The mono node's session folder (a view per stored frame, with its robot pose), its result
    store and labels."""

    def manifest(self) -> SessionManifest:
        return manifest_of(self.node)

    def recording_on(self) -> bool:
        return recording_on(self.node)

    def restore(self, folder: SessionFolder) -> None:
        params = detection_params(str(self.node.p("distortion_model")), float(self.node.p("gamma")))
        for view in list(folder.views):
            det = detect_target(folder.image(view), self.node.target, params, name=view.name)
            self.node.session.restore(det, view.robot_pose)

    def persist(self, img: np.ndarray, stamp_ns: int) -> Any:
        """The ``persist`` callback of a frame (:meth:`..session.live.LiveSession.examine`)."""
        def write(det: Detection, robot_pose: Transform | None) -> str:
            if self.folder is None:
                return ""
            size = self.folder.manifest.image_size
            try:
                if size is not None and size != (img.shape[1], img.shape[0]):
                    raise SessionFolderError(f"the frame is {img.shape[1]}x{img.shape[0]}, the session's "
                                             f"{size[0]}x{size[1]}")
                self.folder.record(det.name, img, stamp_ns, robot_pose)
                return f"written to {self.folder.path}"
            except SessionFolderError as e:
                return self.failed(e)
        return write

    def images(self) -> Any:
        """A view's name -> its recorded frame (None when not recorded), for the report."""
        folder = self.folder
        if folder is None:
            return None

        def image(name: str) -> np.ndarray | None:
            view = next((v for v in folder.views if v.name == name), None)
            try:
                return folder.image(view) if view is not None else None
            except SessionFolderError:
                return None
        return image

    def write_result(self, fill: Any, views: int) -> ResultSet:
        """Write one result set (``fill(folder)``), copy the camera YAML to ``calibration_file`` when
        set, and make it the live result. Raises :class:`~..io.atomic.FileWriteError`."""
        rs = ResultStore(self.base()).write(fill)
        target = str(self.node.p("calibration_file"))
        if target:
            name = f"{self.node.p('camera_name')}.yaml"
            copy_atomic(rs.path(name), target)
            sidecar = sidecar_path(rs.path(name))
            if sidecar.exists():
                copy_atomic(sidecar, sidecar_path(Path(target).expanduser()))
        self.node.history.succeeded(rs.id, views)
        return rs

    def status(self) -> dict[str, Any]:
        return {**self.node.history.status(), **self.folder_status()}


def stereo_manifest(node: NodeCore) -> SessionManifest:
    """What the stereo node records a session with: a shot of the left and the right camera."""
    p = node.p
    return SessionManifest(str(p("target")), str(p("camera_name")), str(p("distortion_model")), float(p("gamma")),
                           frame_id=str(p("left_frame")), child_frame_id=str(p("right_frame")), cameras=SIDES)


class StereoNodeSession(SessionRecording[RecordedStereoNode]):
    """The stereo node's session folder: each stored shot (both frames, then ``session.yaml``
    naming it with its stamps and which camera's view was not used) as it is taken."""

    def manifest(self) -> SessionManifest:
        return stereo_manifest(self.node)

    def recording_on(self) -> bool:
        """``record_session``: ``always``, ``never``, or ``auto`` (with ``output_dir`` or ``resume``)."""
        mode = str(self.node.p("record_session"))
        if mode == "auto":
            return bool(self.node.p("output_dir")) or bool(self.node.p("resume"))
        return mode == "always"

    def restore(self, folder: SessionFolder) -> None:
        params = detection_params(str(self.node.p("distortion_model")), float(self.node.p("gamma")))
        for shot in recorded_stereo_shots(folder, self.node.target, params):
            self.node.session.restore(shot)

    def record_shot(self, name: str, images: tuple[np.ndarray, np.ndarray], stamps_ns: tuple[int, int],
                    not_used: tuple[str, str]) -> str:
        """Write a stored shot; the answer's note (where it went, or why it was not written: then
        counted, and the shot kept in memory); empty when not recording."""
        if self.folder is None:
            return ""
        try:
            self.folder.record_shot(name, images, stamps_ns, not_used)
            return f"written to {self.folder.path}"
        except SessionFolderError as e:
            return self.failed(e)


__all__ = ["FileWriteError", "NodeSession", "RecordedNode", "RecordedStereoNode", "SessionRecording",
           "StereoNodeSession"]
