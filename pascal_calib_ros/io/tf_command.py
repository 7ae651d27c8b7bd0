"""The ``static_transform_publisher`` command that publishes a transform: ROS 2 Jazzy's
``tf2_ros`` with named arguments (``--x --y --z --qx --qy --qz --qw --frame-id --child-frame-id``)."""

from __future__ import annotations

from ..geometry import Transform


def static_transform_command(X: Transform, parent: str, child: str, digits: int = 6) -> str:
    """The command publishing X (p_parent = R p_child + t): the translation (metres) with ``digits``
    decimals, the quaternion with one more."""
    t, q = X.translation, X.quat
    d, e = digits, digits + 1
    return ("ros2 run tf2_ros static_transform_publisher "
            f"--x {t[0]:.{d}f} --y {t[1]:.{d}f} --z {t[2]:.{d}f} --qx {q[0]:.{e}f} --qy {q[1]:.{e}f} --qz {q[2]:.{e}f} "
            f"--qw {q[3]:.{e}f} --frame-id {parent} --child-frame-id {child}")


__all__ = ["static_transform_command"]
