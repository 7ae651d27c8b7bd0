"""A hand-eye result (HAND_EYE.yaml, :mod:`.hand_eye_yaml`) as a URDF joint or a
``static_transform_publisher`` command.

X maps camera-frame points into the parent frame (the tool for eye in hand, the base for eye to
hand), which is both a URDF fixed joint's ``origin`` (the child link's frame in the parent's) and
what ``static_transform_publisher --frame-id parent --child-frame-id camera`` publishes.

- URDF (https://wiki.ros.org/urdf/XML/joint): ``<origin xyz="x y z" rpy="roll pitch yaw"/>``,
  rpy fixed-axis angles, R = Rz(yaw) Ry(pitch) Rx(roll) (scipy's extrinsic "xyz" Euler angles).
- ROS 2 Jazzy ``tf2_ros static_transform_publisher`` with named arguments:
  ``--x --y --z --qx --qy --qz --qw --frame-id --child-frame-id``.

Numbers are written with 9 (translation, metres: a nanometre) and 10 (angles, quaternion)
decimals, far below any hand-eye sigma.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..geometry import Transform
from .tf_command import static_transform_command


def _frames(doc: dict[str, Any]) -> tuple[str, str]:
    parent = str(doc.get("parent_frame") or ("tool0" if doc.get("mode") == "eye_in_hand" else "base_link"))
    return parent, str(doc.get("child_frame") or "camera_optical_frame")


def urdf_joint_text(doc: dict[str, Any], X: Transform, joint_name: str = "") -> str:
    """A fixed ``<joint>`` element placing the camera's frame in its parent (module docstring), with
    the hand-eye sigma as a comment."""
    parent, child = _frames(doc)
    name = joint_name or f"{parent}_to_{child}"
    rpy = X.rotation.as_euler("xyz")
    t = X.translation
    lines = [f"<!-- hand-eye ({doc.get('mode', '?')}): {child} in {parent}"]
    if "translation_std_mm" in doc and "rotation_std_deg" in doc:
        s_t = " ".join(f"{float(v):.3f}" for v in doc["translation_std_mm"])
        s_r = " ".join(f"{float(v):.4f}" for v in doc["rotation_std_deg"])
        lines[0] += f"; std {s_t} mm, {s_r} deg"
    lines[0] += " -->"
    lines += [f'<joint name="{name}" type="fixed">',
              f'  <parent link="{parent}"/>',
              f'  <child link="{child}"/>',
              f'  <origin xyz="{t[0]:.9f} {t[1]:.9f} {t[2]:.9f}" rpy="{rpy[0]:.10f} {rpy[1]:.10f} {rpy[2]:.10f}"/>',
              "</joint>", ""]
    return "\n".join(lines)


def static_transform_text(doc: dict[str, Any], X: Transform) -> str:
    """The ``ros2 run tf2_ros static_transform_publisher`` command that publishes X, a line."""
    return static_transform_command(X, *_frames(doc), digits=9) + "\n"


def transform_of_urdf_origin(xyz: list[float], rpy: list[float]) -> Transform:
    """The transform of a URDF ``origin`` (the inverse of :func:`urdf_joint_text`'s numbers)."""
    from scipy.spatial.transform import Rotation

    return Transform(Rotation.from_euler("xyz", np.asarray(rpy, float)), np.asarray(xyz, float))
