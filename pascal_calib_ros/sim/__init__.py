"""Synthetic sessions with ground truth: the exact renderer (any lens), camera sessions, robot-arm
sessions (used by the demo, the tests and the studies)."""

from .arm import (
    DEFAULT_HAND_EYE,
    DEFAULT_TARGET,
    ArmSpec,
    arm_poses,
    hand_eye_errors,
    render_arm_images,
    simulate_arm_session,
)
from .render import (
    BACKGROUND,
    Pose,
    RenderedView,
    SensorModel,
    apply_sensor,
    features_in_image,
    random_poses,
    reflectance,
    render_view,
)
from .rig import RigSession, RigSpec, render_rig, stereo_pair
from .session import SessionSpec, render_session, render_session_views, session_views

__all__ = ["BACKGROUND", "DEFAULT_HAND_EYE", "DEFAULT_TARGET", "ArmSpec", "Pose", "RenderedView", "RigSession",
           "RigSpec", "SensorModel", "SessionSpec", "apply_sensor", "arm_poses", "features_in_image", "hand_eye_errors",
           "random_poses", "reflectance", "render_arm_images", "render_rig", "render_session", "render_session_views",
           "render_view", "session_views", "simulate_arm_session", "stereo_pair"]
