"""Which node ``calibration_node`` runs: the ``mode`` parameter (``mono`` or ``stereo``), read before
the node is made.

A node's parameter overrides (``--ros-args -p mode:=stereo``, ``--params-file``, remapped node
names) are only known to a node of that name, so a short-lived probe node with the calibration
node's name reads them and is destroyed before the real node is created.
"""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.node import Node

from .stereo_node import StereoCalibrationNode


def requested_mode(node_name: str = "pascal_calib") -> str:
    """The ``mode`` parameter given to ``node_name`` (``mono`` when not given); any other value is
    returned as given (the node it selects refuses it with the reason)."""
    probe = rclpy.create_node(node_name, start_parameter_services=False, enable_rosout=False,
                              automatically_declare_parameters_from_overrides=True)
    try:
        return str(probe.get_parameter("mode").value) if probe.has_parameter("mode") else "mono"
    finally:
        probe.destroy_node()


def make_calibration_node(mono: Callable[[], Node]) -> Node:
    """The node of the ``mode`` parameter: ``mono()`` (the
    :class:`~.calibration_node.CalibrationNode`) or the :class:`~.stereo_node.StereoCalibrationNode`."""
    if requested_mode("pascal_calib") == "stereo":
        return StereoCalibrationNode()
    return mono()
