"""The ``publisher`` node (node name ``pascal_calib_publisher``): a saved result on ``/tf_static``.

``ros2 run pascal_calib_ros publisher --ros-args -p file:=$HOME/calib/wrist/hand_eye.yaml`` (or
``publish.launch.py``) reads a ``hand_eye.yaml``, ``stereo.yaml`` or ``rig.yaml`` at start and broadcasts its transforms
on ``/tf_static`` (:mod:`.tf_static`: transient local, so tf2 listeners started later get it), as the
calibration node did when it made the result, so a cell's frames come back at every start. It checks
the file every ``watch_period`` seconds and broadcasts again when it changes: a recalibration takes
effect without a restart. A file it cannot stand behind (:mod:`..workflows.static_transform`: not
finite, sigma above the calibration node's limits, not a result file) is refused with the reason: at
start the node exits with code 2; later the previous transform stays broadcast and the refusal is
logged. A new file whose frames differ from the broadcast ones is refused too (a static transform
cannot be withdrawn from /tf_static): restart the publisher for new frames.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from ..errors import PascalCalibError
from ..workflows import ResultFileError, StaticTransform, read_result_transforms
from .conversions import transform_msg
from .guard import guarded_callback
from .tf_static import TF_STATIC, StaticTransforms

PARAMS: tuple[tuple[str, Any, str], ...] = (
    ("file", "", "the result to broadcast: a `hand_eye.yaml` (its `parent_frame` → `child_frame`), a "
                 "`stereo.yaml` (`right_in_left`: left → right optical frame) or a `rig.yaml` (the reference "
                 "camera's optical frame → each other camera's), as the calibration node and "
                 "`pascal-calib handeye` / `stereo` / `rig` write them; `~` is expanded (read only)"),
    ("watch_period", 1.0, "seconds between checks of the file; a changed file is read again and, if it can be "
                          "stood behind, broadcast (0: read once) (range 0 to 3600; read only)"),
)


class PublisherNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("pascal_calib_publisher", **kwargs)
        for name, default, desc in PARAMS:
            d = ParameterDescriptor(description=desc, read_only=True)
            if name == "watch_period":
                d.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=3600.0, step=0.0)]
            self.declare_parameter(name, default, d)
        if not str(self.get_parameter("file").value):
            raise ResultFileError("no result file: set file:=PATH (a hand_eye.yaml or stereo.yaml)")
        self.path = Path(str(self.get_parameter("file").value)).expanduser()
        self.tf_static = StaticTransforms(self)
        if self.tf_static.unavailable:
            raise PascalCalibError(self.tf_static.unavailable)
        self.current: list[StaticTransform] = []
        self.digest = ""
        self.broadcasts = 0
        self.refusal = ""
        self._load(at_start=True)
        period = float(self.get_parameter("watch_period").value)
        if period > 0:
            self.create_timer(period, guarded_callback(self, "file check", self._check))

    def _read(self) -> tuple[str, list[StaticTransform]]:
        """The file's checksum and transforms (:class:`ResultFileError` when they cannot be broadcast)."""
        try:
            data = self.path.read_bytes()
        except OSError as e:
            raise ResultFileError(f"{self.path}: cannot read ({e})") from None
        return hashlib.sha256(data).hexdigest(), read_result_transforms(self.path)

    def _load(self, at_start: bool = False) -> None:
        digest, sts = self._read()
        frames = [(st.parent, st.child) for st in sts]
        if self.current and frames != [(st.parent, st.child) for st in self.current]:
            raise ResultFileError(f"{self.path}: its frames changed from "
                                  f"{', '.join(f'{st.parent} -> {st.child}' for st in self.current)} to "
                                  f"{', '.join(f'{a} -> {b}' for a, b in frames)}; a static transform cannot be "
                                  "withdrawn from /tf_static: restart the publisher to broadcast the new frames")
        now = self.get_clock().now().to_msg()
        self.tf_static.send(*(transform_msg(st.pose, st.parent, st.child, now) for st in sts))
        self.current, self.digest, self.refusal = sts, digest, ""
        self.broadcasts += 1
        again = "" if at_start else "the file changed: "
        for st in sts:
            self.get_logger().info(f"{again}broadcasting {st.describe()} on {TF_STATIC} (from {self.path})")

    def _check(self) -> None:
        """Timer: read the file again when its bytes changed; a refusal keeps the previous transform."""
        try:
            digest = hashlib.sha256(self.path.read_bytes()).hexdigest()
        except OSError as e:
            why = f"{self.path}: cannot read ({e}); still broadcasting the previous transform"
            if why != self.refusal:
                self.refusal = why
                self.get_logger().error(why)
            return
        if digest == self.digest:
            return
        try:
            self._load()
        except Exception as e:  # a bad file must never stop the broadcast of the good one
            self.digest = digest  # refused once per version of the file
            self.refusal = f"{e}; still broadcasting the previous transform"
            self.get_logger().error(f"refused: {self.refusal}")

    def stop(self) -> None:
        """Nothing runs outside the executor (for :func:`.spin.run_node`)."""


def main(args: list[str] | None = None) -> int:
    from .spin import run_node

    return run_node(PublisherNode, (PascalCalibError,), "pascal_calib_publisher", SingleThreadedExecutor, args)


if __name__ == "__main__":
    raise SystemExit(main())
