"""The ROS 2 layer, the only one that imports rclpy: the calibration and replay nodes, their
parameters, message conversions and the spin loop."""

__all__ = ["calibration_node", "commit", "conversions", "params", "replay_node", "robot_poses", "spin"]
