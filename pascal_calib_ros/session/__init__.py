"""Live collection, ROS-free and thread-safe: the view collector, the stillness gate and the robot
pose buffer, captures on command, the frame policy of a live session, the live picture."""

from .answer import Answer
from .arm_bag import read_arm_bag
from .arm_session import CaptureSlot, PoseBuffer, StillnessGate
from .collector import ViewCollector, placement_points
from .frame_pairing import SIDES, ApproximatePairer, Dropped
from .guide_overlay import draw_guide
from .guided_live import GuidedLive, GuideView
from .live import NOT_WRITTEN, FrameOutcome, LiveSession, Snapshot, max_motion_of
from .overlay import draw_live_overlay
from .result_history import ResultHistory
from .stereo_live import StereoSession

__all__ = ["NOT_WRITTEN", "SIDES", "Answer", "ApproximatePairer", "CaptureSlot", "Dropped", "FrameOutcome", "GuideView",
           "GuidedLive", "LiveSession", "PoseBuffer", "ResultHistory", "Snapshot", "StereoSession", "StillnessGate",
           "ViewCollector", "draw_guide", "draw_live_overlay", "max_motion_of", "placement_points", "read_arm_bag"]
