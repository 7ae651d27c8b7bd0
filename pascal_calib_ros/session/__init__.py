"""Live collection, ROS-free and thread-safe: the view collector, the stillness gate and the robot
pose buffer, captures on command, the frame policy of a live session, the live picture."""

from .arm_session import CaptureSlot, PoseBuffer, StillnessGate
from .collector import ViewCollector
from .live import FrameOutcome, LiveSession, Snapshot
from .overlay import draw_live_overlay

__all__ = ["CaptureSlot", "FrameOutcome", "LiveSession", "PoseBuffer", "Snapshot", "StillnessGate", "ViewCollector",
           "draw_live_overlay"]
