"""Pair the frames of two cameras by their stamps (approximate time), ROS-free.

A stereo pair's two drivers publish on two topics; a shot is a left and a right frame whose
header stamps differ by at most ``slop`` seconds (0: equal stamps, hardware-synchronised
cameras). :class:`ApproximatePairer` is a two-stream version of ROS ``message_filters``'
``ApproximateTimeSynchronizer``: each side's frames wait in a short queue (stamps increase on
each side); whenever both queues hold frames, the oldest frame overall, ``a``, is matched with the
other side's oldest frame ``b`` (every frame there is at least as new as ``a``):

* ``b`` is within ``slop`` of ``a`` and no newer frame of ``a``'s side already queued is closer
  to ``b``: a pair, and both leave the queues;
* a newer frame of ``a``'s side is closer to ``b``: ``a`` is dropped (superseded);
* ``b`` is more than ``slop`` after ``a``: no later frame of ``b``'s side can be closer, so ``a``
  can never pair and is dropped (the gap is kept for the reason shown to the user).

A queue that overflows (the other camera sends nothing) drops its oldest frame. Every dropped
frame is returned with its reason, so that the node can count it, say why frames arrive but never
pair, and acknowledge it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

SIDES = ("left", "right")


@dataclass
class Frame:
    """One camera's frame waiting for its partner: its side (0 left, 1 right), stamp (ns) and
    whatever the caller pairs (a message)."""

    side: int
    stamp_ns: int
    item: Any


@dataclass
class Dropped:
    """A frame that will never pair, and why."""

    frame: Frame
    reason: str


@dataclass
class PairingStats:
    """Counts of a pairer since its start."""

    received: list[int] = field(default_factory=lambda: [0, 0])
    paired: int = 0
    dropped: list[int] = field(default_factory=lambda: [0, 0])
    since_pair: list[int] = field(default_factory=lambda: [0, 0])  # frames received since the last pair
    last_gap_s: float | None = None  # the stamp difference that last stopped a frame from pairing
    last_pair_gap_s: float | None = None  # the stamp difference of the last pair

    def never_paired_note(self, slop_s: float, topics: tuple[str, str] = SIDES) -> str:
        """Why frames arrive but do not pair and what to do (empty while frames pair, or none arrive):
        :data:`STUCK_FRAMES` or more frames of a side since the last pair (or the start) and either
        nothing from the other side, or frames from both that never came within ``slop_s``."""
        left, right = self.since_pair
        if max(left, right) < STUCK_FRAMES:
            return ""
        since = "since the last pair" if self.paired else "so far"
        if not left or not right:
            have, missing = (topics[0], topics[1]) if left else (topics[1], topics[0])
            return (f"{max(left, right)} frame(s) arrived on {have} {since} but none on {missing}: check that "
                    "camera's driver, the remapping of its topic and its transport")
        if min(left, right) < STUCK_FRAMES:
            return ""
        gap = f"their stamps differ by {self.last_gap_s:.3f} s" if self.last_gap_s is not None else \
            "no two stamps came close enough"
        return (f"frames arrive but never pair: {left} left and {right} right frame(s) {since}, {gap}, more than "
                f"sync_slop {slop_s:g} s; synchronise the cameras' clocks (or trigger them together), or raise "
                "sync_slop if the target is held still")


STUCK_FRAMES = 3  # frames of each side since the last pair after which the status says why none paired


class ApproximatePairer:
    """Pairs two streams of stamped frames (module docstring). Not thread-safe: call it from one
    thread (or under a lock)."""

    def __init__(self, slop_s: float, queue_size: int = 8) -> None:
        if slop_s < 0:
            raise ValueError(f"sync slop must be >= 0 s, got {slop_s}")
        if queue_size < 1:
            raise ValueError(f"queue size must be >= 1, got {queue_size}")
        self.slop_ns = round(slop_s * 1e9)
        self.queue_size = queue_size
        self.queues: tuple[deque[Frame], deque[Frame]] = (deque(), deque())
        self.stats = PairingStats()

    @property
    def slop_s(self) -> float:
        return self.slop_ns * 1e-9

    def set_slop(self, slop_s: float) -> None:
        if slop_s < 0:
            raise ValueError(f"sync slop must be >= 0 s, got {slop_s}")
        self.slop_ns = round(slop_s * 1e9)

    def push(self, side: int, stamp_ns: int, item: Any) -> tuple[list[tuple[Frame, Frame]], list[Dropped]]:
        """Add one frame of ``side`` (0 left, 1 right); returns the pairs (left, right) it completes
        and the frames that can no longer pair."""
        if side not in (0, 1):
            raise ValueError(f"side must be 0 (left) or 1 (right), got {side}")
        self.stats.received[side] += 1
        self.stats.since_pair[side] += 1
        dropped: list[Dropped] = []
        q = self.queues[side]
        if q and stamp_ns < q[-1].stamp_ns:  # stamps went back (a driver restarted, a replay looped)
            dropped += [Dropped(f, f"the {SIDES[side]} stamps went back in time; queue cleared") for f in q]
            q.clear()
        q.append(Frame(side, stamp_ns, item))
        if len(q) > self.queue_size:
            other = SIDES[1 - side]
            dropped.append(Dropped(q.popleft(), f"no {other} frame arrived within the {self.queue_size} newest "
                                                f"{SIDES[side]} frames"))
        pairs = self._match(dropped)
        for d in dropped:
            self.stats.dropped[d.frame.side] += 1
        return pairs, dropped

    def _match(self, dropped: list[Dropped]) -> list[tuple[Frame, Frame]]:
        pairs: list[tuple[Frame, Frame]] = []
        while self.queues[0] and self.queues[1]:
            heads = (self.queues[0][0], self.queues[1][0])
            s = 0 if heads[0].stamp_ns <= heads[1].stamp_ns else 1  # the oldest frame overall
            a, b = heads[s], heads[1 - s]
            gap = b.stamp_ns - a.stamp_ns
            if gap > self.slop_ns:
                self.stats.last_gap_s = gap * 1e-9
                self.queues[s].popleft()
                dropped.append(Dropped(a, f"no {SIDES[1 - s]} frame within sync_slop {self.slop_s:g} s (the next "
                                          f"one is {gap * 1e-9:.3f} s later)"))
                continue
            nxt = self.queues[s][1] if len(self.queues[s]) > 1 else None
            if nxt is not None and abs(nxt.stamp_ns - b.stamp_ns) < gap:
                self.queues[s].popleft()
                dropped.append(Dropped(a, f"a newer {SIDES[s]} frame is closer to the {SIDES[1 - s]} frame"))
                continue
            self.queues[0].popleft()
            self.queues[1].popleft()
            self.stats.paired += 1
            self.stats.since_pair = [0, 0]
            self.stats.last_pair_gap_s = gap * 1e-9
            pairs.append((a, b) if s == 0 else (b, a))
        return pairs

    def clear(self) -> list[Frame]:
        """Empty the queues; returns the frames that waited."""
        out = [*self.queues[0], *self.queues[1]]
        self.queues[0].clear()
        self.queues[1].clear()
        return out
