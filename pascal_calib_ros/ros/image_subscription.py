"""An image subscription whose QoS matches its topic's publishers (``qos:=auto``), one per topic.

A reliable subscriber never connects to a best-effort publisher and shows nothing, the most
common "no images" failure of ROS 2 camera set-ups (and, with two cameras, of one of them).
With ``auto`` the subscription is reliable (no loss of large frames, and the default before
anyone publishes) and becomes best-effort as soon as a best-effort publisher of the topic is seen;
:meth:`MatchedImageSubscription.ensure` re-checks (the node calls it every second).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy


class MatchedImageSubscription:
    """The subscription of ``node`` to ``topic`` (``msg_type``) with ``callback``; ``mode()`` gives
    the ``qos`` parameter's value (``auto``, ``reliable`` or ``best_effort``)."""

    def __init__(self, node: Any, topic: str, msg_type: Any, callback: Callable[[Any], None],
                 mode: Callable[[], str], group: Any) -> None:
        self.node, self.topic, self.msg_type, self.callback = node, topic, msg_type, callback
        self.mode, self.group = mode, group
        self.sub: Any = None
        self.reliability: ReliabilityPolicy | None = None
        self.ensure()

    @property
    def resolved(self) -> str:
        return str(self.node.resolve_topic_name(self.topic))

    def wanted(self) -> ReliabilityPolicy:
        mode = self.mode()
        if mode == "reliable":
            return ReliabilityPolicy.RELIABLE
        if mode == "best_effort":
            return ReliabilityPolicy.BEST_EFFORT
        infos = self.node.get_publishers_info_by_topic(self.resolved)
        if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
            return ReliabilityPolicy.BEST_EFFORT
        return ReliabilityPolicy.RELIABLE

    def ensure(self) -> None:
        """(Re)subscribe if the wanted reliability changed; logs the change."""
        want = self.wanted()
        if self.sub is not None and want == self.reliability:
            return
        if self.sub is not None:
            self.node.destroy_subscription(self.sub)
        qos = QoSProfile(depth=2, reliability=want, history=HistoryPolicy.KEEP_LAST)
        self.sub = self.node.create_subscription(self.msg_type, self.topic, self.callback, qos,
                                                 callback_group=self.group)
        self.reliability = want
        self.node.get_logger().info(f"subscribed to {self.resolved} with "
                                    f"{'reliable' if want == ReliabilityPolicy.RELIABLE else 'best-effort'} QoS")

    @property
    def qos_name(self) -> str:
        return "reliable" if self.reliability == ReliabilityPolicy.RELIABLE else "best_effort"

    def publishers(self) -> int:
        return int(self.node.count_publishers(self.resolved))
