"""Hand-eye calibration: the camera's pose on the robot (eye in hand) or in the robot's base (eye to
hand) jointly with the intrinsics, with the robot chain as a measurement (:mod:`.session`)."""

from .closed_form import chain_disagreement, chain_pose, check_robot_poses, hand_eye_closed_form, park_martin
from .options import HandEyeError, HandEyeOptions, HandEyeResult, HandEyeView
from .session import calibrate_hand_eye
from .sigma import arm_field_covariance, arm_field_share

__all__ = ["HandEyeError", "HandEyeOptions", "HandEyeResult", "HandEyeView", "arm_field_covariance",
           "arm_field_share", "calibrate_hand_eye", "chain_disagreement", "chain_pose", "check_robot_poses",
           "hand_eye_closed_form", "park_martin"]
