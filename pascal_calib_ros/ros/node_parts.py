"""What a part of a calibration node needs of the node, as a :class:`typing.Protocol`.

A node is made of parts (its guide, session folder, status, verification); each part is given the
node and declares what it uses of it as a protocol in its own module, built on :class:`NodeCore`
here. The parts then import no node module, the node modules import the parts, and mypy checks at
the node's call that the node has what the part uses (issue 35: no import cycle, those made by
annotations included)."""

from __future__ import annotations

from typing import Any, Protocol

from rclpy.impl.rcutils_logger import RcutilsLogger


class NodeCore(Protocol):
    """What every part uses of its node: the parameters and the logger
    (:class:`.node_base.CalibrationNodeBase` has both)."""

    def p(self, name: str) -> Any: ...

    def get_logger(self) -> RcutilsLogger: ...


__all__ = ["NodeCore"]
