"""Hand-eye calibration: the camera's pose on the robot (eye in hand) or in the robot's base (eye to
hand) jointly with the intrinsics, with the robot chain as a measurement (:mod:`.session`)."""

from .chain import ChainProblem, RobotChain
from .chain_refinement import ChainStart, refine_chain
from .closed_form import (
    chain_disagreement,
    chain_pose,
    check_robot_poses,
    complete_ring_poses,
    hand_eye_closed_form,
    park_martin,
)
from .labelling import relabelled, target_symmetries
from .options import HandEyeError, HandEyeOptions, HandEyeResult, HandEyeView
from .session import calibrate_hand_eye, calibrate_hand_eye_warm
from .sigma import arm_field_covariance, arm_field_share
from .view_poses import camera_pose
from .warm import HandEyeStart

__all__ = ["ChainProblem", "ChainStart", "HandEyeError", "HandEyeOptions", "HandEyeResult", "HandEyeStart",
           "HandEyeView", "RobotChain", "arm_field_covariance", "arm_field_share", "calibrate_hand_eye",
           "calibrate_hand_eye_warm", "camera_pose", "chain_disagreement", "chain_pose", "check_robot_poses",
           "complete_ring_poses", "hand_eye_closed_form", "park_martin", "refine_chain", "relabelled",
           "target_symmetries"]
