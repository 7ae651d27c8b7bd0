"""Which result is live and whether the last attempt failed: what ``~/status`` shows and what
``~/commit`` checks before it hands a calibration to the driver (a stale result is never committed
as if it were new)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass


def clock(at: float) -> str:
    """Local wall time ``HH:MM:SS`` of a ``time.time()``."""
    return time.strftime("%H:%M:%S", time.localtime(at))


@dataclass(frozen=True)
class LiveResult:
    """The result on the node's topics: its id (its result set's folder), when, from how many views."""

    id: str
    at: float
    views: int

    def describe(self) -> str:
        return f"result {self.id} (calibrated {clock(self.at)} from {self.views} views)"


class ResultHistory:
    """The live result and the last failed attempt after it (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.live: LiveResult | None = None
        self.failed = ""  # why the last attempt failed, when it came after the live result
        self.failed_at = 0.0

    def succeeded(self, result_id: str, views: int, at: float | None = None) -> LiveResult:
        with self._lock:
            self.live = LiveResult(result_id, time.time() if at is None else at, views)
            self.failed, self.failed_at = "", 0.0
            return self.live

    def attempt_failed(self, reason: str, at: float | None = None) -> None:
        with self._lock:
            self.failed, self.failed_at = reason, time.time() if at is None else at

    def commit_problem(self) -> str:
        """Why the live result must not be committed now (empty: it may be): none yet, or the last
        attempt failed after it (committing would look like the new calibration)."""
        with self._lock:
            if self.live is None:
                return "no calibration to commit: call ~/calibrate first"
            if self.failed:
                return (f"not committed: the last ~/calibrate ({clock(self.failed_at)}) failed ({self.failed}); the "
                        f"live {self.live.describe()} is older. Calibrate successfully, then commit")
            return ""

    def status(self) -> dict[str, str]:
        """``result_id`` and ``last_attempt`` for ``~/status``."""
        with self._lock:
            live = self.live
            last = (f"failed at {clock(self.failed_at)}: {self.failed}" if self.failed
                    else ("succeeded" if live is not None else "none"))
            return {"result_id": live.id if live else "", "result_at": clock(live.at) if live else "",
                    "last_attempt": last}
