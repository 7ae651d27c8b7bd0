"""Synthetic sessions with ground truth: the exact renderer (any lens), camera sessions, robot-arm
sessions (used by the demo, the tests and the studies)."""

from .arm import ArmSpec, simulate_arm_session
from .render import Pose, RenderedView, SensorModel, render_view
from .session import SessionSpec, render_session, render_session_views

__all__ = ["ArmSpec", "Pose", "RenderedView", "SensorModel", "SessionSpec", "render_session", "render_session_views",
           "render_view", "simulate_arm_session"]
