"""``~/status`` of the calibration node's stereo mode: the shots, each camera's views, coverage and
rejections, the frames received, paired and dropped per camera and, when frames arrive but never
pair, why (their stamps differ by more than ``sync_slop``, or one camera sends nothing)."""

from __future__ import annotations

import threading
from typing import Protocol

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header

from ..session import SIDES, ApproximatePairer, ResultHistory, StereoSession
from .image_subscription import MatchedImageSubscription
from .node_parts import NodeCore
from .tf_static import StaticTransforms


class StereoStatusNode(NodeCore, Protocol):
    """What the stereo ``~/status`` reads of the node (:class:`.stereo_node.StereoCalibrationNode`)."""

    session: StereoSession
    pairer: ApproximatePairer
    _pending_cv: threading.Condition  # held while the pairer and the pair counts are read
    pairs_examined: int
    pairs_dropped: int
    calibrating: threading.Lock
    last_error: str
    frames_bad: list[int]
    frames_not_saved: int
    subs: tuple[MatchedImageSubscription, ...]
    result_line: str
    report_note: str
    history: ResultHistory
    tf_static: StaticTransforms

    def get_name(self) -> str: ...

    def sync_note(self) -> str: ...

    def busy_note(self) -> str: ...

    def pairs_dropped_session(self) -> int: ...

    def header(self, side: int) -> Header: ...


def stereo_status_message(node: StereoStatusNode) -> DiagnosticArray:
    """The stereo node's status now (one DiagnosticStatus with key-values)."""
    s = node.session
    with s.lock:
        col = s.collector
        cov, both, shots, ready = col.coverage(), col.both, len(col.shots), col.ready
        views = [len(c.views) for c in col.cameras]
        rejected, last_rej = dict(col.rejected), col.last_rejection
        cam_rejected = [dict(c.rejected) for c in col.cameras]
    with node._pending_cv:
        stats = node.pairer.stats
        received, paired, unpaired = list(stats.received), stats.paired, list(stats.dropped)
        pair_gap, examined, dropped = stats.last_pair_gap_s, node.pairs_examined, node.pairs_dropped
    never, busy = node.sync_note(), node.busy_note()
    st = DiagnosticStatus(name=f"{node.get_name()}: stereo calibration", hardware_id=str(node.p("camera_name")))
    if node.calibrating.locked():
        st.level, st.message = DiagnosticStatus.OK, "calibrating"
    elif never:
        st.level, st.message = DiagnosticStatus.ERROR, never
    elif ready:
        st.level, st.message = DiagnosticStatus.OK, f"ready: {both} shots both cameras see; call ~/calibrate"
    else:
        st.level = DiagnosticStatus.WARN
        st.message = (f"collecting: {both}/{col.min_views} shots both cameras see; coverage "
                      + "; ".join(f"{side} " + " ".join(f"{k} {v:.2f}" for k, v in cov[c].items())
                                  for c, side in enumerate(SIDES)))
        if busy:
            st.message += "; " + busy
    kv: dict[str, object] = {
        "mode": "stereo", "shots_stored": shots, "shots_both": both, "ready": ready,
        "views_left": views[0], "views_right": views[1], "shots_rejected": sum(rejected.values()),
        "last_rejection": last_rej, "last_error": node.last_error,
        "frames_received_left": received[0], "frames_received_right": received[1],
        "frames_unpaired_left": unpaired[0], "frames_unpaired_right": unpaired[1],
        "pairs": paired, "pairs_examined": examined, "pairs_dropped": dropped,
        "pairs_dropped_session": node.pairs_dropped_session(),
        "frames_bad_left": node.frames_bad[0], "frames_bad_right": node.frames_bad[1],
        "frames_not_saved": node.frames_not_saved,
        "last_pair_stamp_difference_s": "" if pair_gap is None else f"{pair_gap:.6f}",
        "sync_slop": node.pairer.slop_s, "sync_note": never,
        "qos_left": node.subs[0].qos_name, "qos_right": node.subs[1].qos_name,
        "publishers_left": node.subs[0].publishers(), "publishers_right": node.subs[1].publishers(),
        **{f"coverage_{side}_{k}": round(v, 3) for c, side in enumerate(SIDES) for k, v in cov[c].items()},
        **{f"rejected: {k}": v for k, v in sorted(rejected.items())},
        **{f"rejected {side}: {k}": v for c, side in enumerate(SIDES) for k, v in sorted(cam_rejected[c].items())},
        "result": node.result_line, **node.history.status(), "report": node.report_note,
        "tf_static": node.tf_static.describe(),
    }
    st.values = [KeyValue(key=k, value=str(v)) for k, v in kv.items()]
    return DiagnosticArray(header=node.header(0), status=[st])
