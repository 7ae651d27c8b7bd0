#!/usr/bin/env python3
"""A guided robot-arm calibration: the script a robot cell's engineer adapts.

The calibration node runs with robot poses and hand-eye, views stored on ``~/capture`` only::

    ros2 run pascal_calib_ros calibration_node --ros-args -r image:=/camera/image_raw \\
        -p target:=ring_grid_a4 -p robot_pose_topic:=/tool_pose -p hand_eye:=eye_in_hand \\
        -p collect:=on_capture -p min_views:=3 -p goal_sigma_px:=0.1

This script moves the arm to a few start poses you choose (``START_POSES``) and captures a view at
each, then loops: ``~/suggest`` (the next tool poses, ranked, on the latched
``~/suggested_tool_poses``) → move to the best pose the arm can reach → ``~/capture``, until
``~/suggest`` answers ``done`` (the recalibrated views reach ``goal_sigma_px`` and the hand-eye
goals), then ``~/calibrate``. Fill in :func:`move_arm` (and ``START_POSES``) for your robot::

    python3 tools/guided_arm_example.py [--node /pascal_calib] [--max-views 20] [--no-calibrate]

The loop itself (:class:`GuidedArmLoop`) runs on any rclpy node and executor; the end-to-end test
(test/ros/test_ros_guide.py) drives it with a simulated arm.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from typing import Any

# ---------------------------------------------------------------------------------------------
# USER: fill in these two for your robot.
# ---------------------------------------------------------------------------------------------
# Three or more tool poses (robot_base_frame, as the node's robot poses) to start from, each with the
# whole target in view, tilted about different axes: [x, y, z] m and [qx, qy, qz, qw].
START_POSES: list[tuple[list[float], list[float]]] = []


def move_arm(pose: Any) -> bool:
    """USER: move the tool (robot_tool_frame) to ``pose`` (geometry_msgs/PoseStamped in
    robot_base_frame), wait until the arm stands still, and return True; return False when the
    pose cannot be reached (no IK solution, a collision, a joint limit): the loop then tries the
    next ranked pose. E.g. with MoveIt: ``move_group.set_pose_target(pose); return
    move_group.go(wait=True)``."""
    raise NotImplementedError("fill in move_arm() with your robot's motion command (MoveIt, your vendor's driver)")
# ---------------------------------------------------------------------------------------------


class GuidedArmLoop:
    """suggest → move → capture until done (module docstring), on ``node`` spun by ``executor``."""

    def __init__(self, node: Any, executor: Any, move: Callable[[Any], bool], calibration_node: str = "/pascal_calib",
                 log: Callable[[str], None] = print) -> None:
        from geometry_msgs.msg import PoseArray
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        self.node, self.executor, self.move, self.log = node, executor, move, log
        self.prefix = calibration_node.rstrip("/")
        self.ranked: list[Any] = []
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(PoseArray, f"{self.prefix}/suggested_tool_poses", self.ranked.append, latched)
        self._clients: dict[str, Any] = {}

    def call(self, service: str, timeout: float = 120.0) -> Any:
        """Call the calibration node's Trigger service ``service`` (e.g. "suggest"); its response."""
        from std_srvs.srv import Trigger

        cli = self._clients.get(service)
        if cli is None:
            cli = self._clients[service] = self.node.create_client(Trigger, f"{self.prefix}/{service}")
            if not cli.wait_for_service(timeout_sec=20.0):
                raise RuntimeError(f"{self.prefix}/{service} is not available: is the calibration node running?")
            self._spin(lambda: False, 0.5)  # the response reader matched before the first call (DDS)
        fut = cli.call_async(Trigger.Request())
        if not self._spin(fut.done, timeout):
            raise RuntimeError(f"no answer from {self.prefix}/{service} within {timeout} s")
        return fut.result()

    def _spin(self, until: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not until():
            self.executor.spin_once(timeout_sec=0.05)
        return until()

    def capture(self) -> bool:
        r = self.call("capture", 30.0)
        self.log(f"capture: {r.message}")
        return bool(r.success)

    def start(self, poses: Sequence[Any]) -> int:
        """Move to each start pose (PoseStamped) and capture; returns the views stored."""
        return sum(self.move(p) and self.capture() for p in poses)

    def run(self, max_views: int = 20) -> tuple[bool, list[str]]:
        """Loop until ``~/suggest`` says done or ``max_views`` guided views were captured; returns
        (done, the answers of ``~/suggest``). A refusal of ``~/suggest`` (too few views, nothing
        inside the trust region) is a RuntimeError with its reason."""
        from geometry_msgs.msg import PoseStamped

        answers: list[str] = []
        captured = 0
        while True:
            self.ranked.clear()
            r = self.call("suggest")
            answers.append(r.message)
            self.log(f"suggest: {r.message}")
            if not r.success:
                raise RuntimeError(r.message)
            if r.message.startswith("done"):
                return True, answers
            if captured >= max_views:
                return False, answers
            if not self._spin(lambda: bool(self.ranked), 10.0):
                raise RuntimeError(f"no {self.prefix}/suggested_tool_poses received after ~/suggest")
            arr = self.ranked[-1]
            for k, p in enumerate(arr.poses):
                if self.move(PoseStamped(header=arr.header, pose=p)):
                    break
                self.log(f"suggestion {k + 1} unreachable; trying the next")
            else:
                raise RuntimeError("none of the suggested tool poses is reachable: widen the start poses' spread")
            captured += self.capture()


def _pose_stamped(node: Any, frame: str, t: list[float], q: list[float]) -> Any:
    from geometry_msgs.msg import PoseStamped

    msg = PoseStamped()
    msg.header.frame_id, msg.header.stamp = frame, node.get_clock().now().to_msg()
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = t
    msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = q
    return msg


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--node", default="/pascal_calib", help="the calibration node's name")
    ap.add_argument("--base-frame", default="base_link", help="robot_base_frame of the start poses")
    ap.add_argument("--max-views", type=int, default=20, help="stop after this many guided views")
    ap.add_argument("--no-calibrate", action="store_true", help="do not call ~/calibrate at the end")
    args = ap.parse_args(argv)

    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    rclpy.init()
    node = rclpy.create_node("guided_arm_example")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        loop = GuidedArmLoop(node, executor, move_arm, args.node)
        if not START_POSES:
            print("START_POSES is empty: the node needs 3 or more stored views with a robot pose already "
                  "(fill in START_POSES, or capture them yourself first)")
        stored = loop.start([_pose_stamped(node, args.base_frame, t, q) for t, q in START_POSES])
        print(f"{stored} start view(s) stored")
        try:
            done, _ = loop.run(args.max_views)
        except RuntimeError as e:
            print(f"stopped: {e}")
            return 2
        print("done" if done else f"not done after {args.max_views} guided views")
        if not args.no_calibrate:
            r = loop.call("calibrate", 300.0)
            print(f"calibrate: {r.message}")
            return 0 if r.success else 1
        return 0 if done else 1
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
