"""The calibration node's session folder and result sets: every stored view written as it is taken
(:mod:`..io.session_folder`), a session continued after a crash (``resume:=true``), and each
result written as one set and labelled (:mod:`..workflows.result_set`,
:mod:`..session.result_history`)."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..detect import detect_target
from ..geometry import Transform
from ..io import FileWriteError, SessionFolder, SessionFolderError, SessionManifest, is_session_folder, sidecar_path
from ..session import NOT_WRITTEN
from ..workflows import ResultSet, ResultStore, copy_atomic, detection_params, output_folder
from .params import ParameterError

if TYPE_CHECKING:
    import numpy as np

    from ..detect import Detection
    from .calibration_node import CalibrationNode

SESSIONS = "sessions"
_NUMBER = re.compile(r"(\d+)$")


def manifest_of(node: CalibrationNode) -> SessionManifest:
    """What the node records a session with (its parameters)."""
    p = node.p
    return SessionManifest(str(p("target")), str(p("camera_name")), str(p("distortion_model")), float(p("gamma")),
                           str(p("hand_eye")), str(p("robot_base_frame")) if node.pose_topic else "",
                           str(p("robot_tool_frame")) if node.pose_topic else "")


def recording_on(node: CalibrationNode) -> bool:
    """``record_session``: ``always``, ``never``, or ``auto`` (with ``collect:=on_capture`` or ``output_dir``)."""
    mode = str(node.p("record_session"))
    if mode == "auto":
        return str(node.p("collect")) == "on_capture" or bool(node.p("output_dir")) or bool(node.p("resume"))
    return mode == "always"


def newest_session(sessions: Path) -> Path | None:
    """The newest session folder under ``sessions`` (by name: they are named by time)."""
    found = sorted(p for p in sessions.glob("*") if is_session_folder(p)) if sessions.is_dir() else []
    return found[-1] if found else None


class NodeSession:
    """The node's session folder (None when not recording), its result store and labels."""

    def __init__(self, node: CalibrationNode) -> None:
        self.node = node
        self.folder: SessionFolder | None = None
        self.not_written = 0
        self.last_error = ""
        self.name_offset = 0  # resumed views keep their names; new frames are numbered after them
        if recording_on(node):
            self.folder = self._open()

    def base(self) -> Path:
        return output_folder(str(self.node.p("camera_name")), str(self.node.p("output_dir")))

    def _open(self) -> SessionFolder:
        node, manifest = self.node, manifest_of(self.node)
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
        """Detect the folder's views again and store them in the live session; returns how many."""
        if self.folder is None or not self.node.p("resume"):
            return 0
        params = detection_params(str(self.node.p("distortion_model")), float(self.node.p("gamma")))
        for view in list(self.folder.views):
            det = detect_target(self.folder.image(view), self.node.target, params, name=view.name)
            self.node.session.restore(det, view.robot_pose)
            m = _NUMBER.search(view.name)
            if m:
                self.name_offset = max(self.name_offset, int(m.group(1)) + 1)
        return len(self.folder.views)

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
                self.not_written += 1
                self.last_error = f"{NOT_WRITTEN} to the session folder: {e}"
                self.node.get_logger().error(self.last_error, throttle_duration_sec=5.0)
                return self.last_error
        return write

    def clear(self) -> str:
        """``~/reset``: the folder starts over (the cleared views are kept); what happened."""
        if self.folder is None:
            return ""
        try:
            n = self.folder.clear()
        except SessionFolderError as e:
            return f"; the session folder could not start over: {e}"
        return f"; {n} recorded view(s) kept in {self.folder.path} (cleared-*.session.yaml)" if n else ""

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
        out: dict[str, Any] = dict(self.node.history.status())
        out["session_folder"] = str(self.folder.path) if self.folder is not None else "(not recording)"
        if self.folder is not None:
            out["session_views_written"] = len(self.folder.views)
            out["session_views_not_written"] = self.not_written
        return out


__all__ = ["FileWriteError", "NodeSession"]
