"""The fault study of issue 34 (README, "Sessions nothing loses"): through the real node over DDS,

1. a 20-view eye-in-hand session (the ring, 640x480) captured as an arm script would, once
   without interruption and once with the node killed by SIGKILL at ``--kills`` random moments
   (while views are captured, and while ``~/calibrate`` writes its results) and started again
   with ``resume:=true`` each time: the same views, the same result to the printed digit, and
   after every kill a session file that reads back and a result set that is whole;
2. the session's recording replayed ``--loops`` times with its own stamps (time going back at every
   pass) and one robot pose stamped an hour ahead: every capture after them succeeds;
3. every service called ``--calls`` times in random order while frames stream: the process stays
   up and every answer says what happened.

Run inside the private network namespace (DDS on loopback only)::

    tools/in_netns python tools/fault_study.py --kills 20 --calls 1000
"""

from __future__ import annotations

import argparse
import random
import signal
import tempfile
import threading
import time
from collections import Counter
from functools import partial
from pathlib import Path
from typing import Any

import yaml
from arm_cell import Cell
from diagnostic_msgs.msg import DiagnosticArray
from node_processes import NodeProcess, RosClient

from pascal_calib_ros.io.session_folder import SessionFolder
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.targets import resolve_target

PARAMS = {"collect": "on_capture", "robot_pose_topic": "/tool_pose", "hand_eye": "eye_in_hand", "min_views": 6,
          "capture_timeout": 5.0, "camera_name": "cell_cam"}
CAPTURE_S, CALIBRATE_S = 1.8, 6.0  # about what a capture and ~/calibrate take here (the kills' time range)
SERVICES = ("calibrate", "reset", "commit", "capture", "verify", "suggest", "skip_suggestion")


def result_of(out: Path) -> dict[str, Any]:
    """The printed digits of the current result: K and the hand-eye transform."""
    cam = yaml.safe_load((out / "cell_cam.yaml").read_text())
    he = yaml.safe_load((out / "hand_eye.yaml").read_text())
    return {"K": [f"{x:.6g}" for x in cam["camera_matrix"]["data"]],
            "t": [f"{x:.6g}" for x in he["translation"]], "q": [f"{x:.6g}" for x in he["rotation"]]}


def whole_set(out: Path) -> bool:
    """The current result set holds the camera YAML, its record and hand_eye.yaml (or there is none)."""
    cur = out / "current"
    if not cur.exists():
        return True
    names = {p.name for p in cur.iterdir()}
    return {"cell_cam.yaml", "cell_cam.calibration.json", "hand_eye.yaml"} <= names


def _running(status: list[Any], node: NodeProcess) -> bool:
    """The node sent a status (it spins), or its process ended."""
    return bool(status) or node.proc.poll() is not None


def call(client: RosClient, node: NodeProcess, name: str, timeout: float) -> Any:
    """A Trigger call that gives up (None) as soon as the node's process has ended."""
    from std_srvs.srv import Trigger

    cli = client.node.create_client(Trigger, f"/pascal_calib/{name}")
    try:
        if not client.spin_until(lambda: cli.service_is_ready() or node.proc.poll() is not None, 60) or \
                node.proc.poll() is not None:
            return None
        client.spin_until(lambda: False, 2.0)  # the response writer matches the new client (slow when loaded)
        fut = cli.call_async(Trigger.Request())
        client.spin_until(lambda: fut.done() or node.proc.poll() is not None, timeout)
        return fut.result() if fut.done() else None
    finally:
        client.node.destroy_client(cli)


def session_run(work: Path, sim: Any, dom: int, kills: int, rng: random.Random) -> tuple[dict[str, Any], list[str]]:
    """Capture every view and calibrate, killing the node ``kills`` times at random moments; returns
    the result's digits and what happened at each kill."""
    session, out = work / "session", work / "out"
    params = {**PARAMS, "session_dir": str(session), "output_dir": str(out)}
    work.mkdir(parents=True, exist_ok=True)
    client = RosClient(dom)
    cell = Cell(client, sim.images["ring_a4"], sim.robot_poses)
    status: list[Any] = []
    client.node.create_subscription(DiagnosticArray, "/pascal_calib/status", status.append, 10)
    n, life = len(sim.robot_poses), 0
    events: list[str] = []
    phase = ["start-up"]

    def kill(proc: Any) -> None:
        proc.send_signal(signal.SIGKILL)
        phase.append(phase[0])  # where the kill landed
    try:
        while True:
            resume = (session / "session.yaml").exists()
            node = NodeProcess("calibration_node", {**params, "resume": resume}, dom, work / f"life{life}.log")
            life += 1
            phase[:] = ["start-up"]
            killer = None
            if len(events) < kills:  # a moment in start-up (a quarter of the kills), the captures or ~/calibrate
                left = n - (len(SessionFolder.open(session).views) if resume else 0)
                delay = rng.uniform(0.0, 4.0) if rng.random() < 0.25 else None
                if delay is None:  # once the node runs (its first status): a moment in what is left to do
                    status.clear()
                    client.spin_until(partial(_running, status, node), 120)
                    phase[0] = "the first capture"
                    delay = rng.uniform(0.0, CAPTURE_S * left + CALIBRATE_S)
                killer = threading.Timer(delay, kill, (node.proc,))
                killer.start()
            done = False
            while node.proc.poll() is None:
                recorded = len(SessionFolder.open(session).views) if (session / "session.yaml").exists() else 0
                if recorded < n:
                    phase[0] = f"capturing view {recorded + 1}"
                    cell.rest(recorded)
                    call(client, node, "capture", 15)
                    continue
                phase[0] = "~/calibrate (solving, writing the result set)"
                r = None
                for _ in range(3):  # a request or answer lost while DDS matches a new client: ask again
                    r = call(client, node, "calibrate", 900)
                    if r is not None or node.proc.poll() is not None:
                        break
                done = r is not None and r.success
                break
            if killer is not None:
                killer.join()
                node.proc.wait(10)
                views = SessionFolder.open(session).views if (session / "session.yaml").exists() else []  # reads back
                events.append(f"kill {len(events) + 1} during {phase[-1]}: {len(views)} view(s) recorded, result set "
                              f"whole: {whole_set(out)}")
            else:
                assert node.stop() == 0, node.log()
                if not done:
                    raise RuntimeError(f"calibration failed without a kill:\n{node.log()}")
            if done:
                return result_of(out), events
    finally:
        client.close()


def service_storm(work: Path, sim: Any, dom: int, calls: int, rng: random.Random, frame_hz: float) -> Counter:
    """Every service ``calls`` times in random order while the arm moves and frames stream."""
    node = NodeProcess("calibration_node", {**PARAMS, "capture_timeout": 1.0, "output_dir": str(work / "storm")},
                       dom, work / "storm.log")
    client = RosClient(dom)
    cell = Cell(client, sim.images["ring_a4"], sim.robot_poses, frame_hz)
    answers: Counter = Counter()
    try:
        for i in range(calls):
            if i % 5 == 0:
                cell.k = rng.randrange(len(sim.robot_poses))
            name = rng.choice(SERVICES)
            r = call(client, node, name, 120)
            if r is None:
                raise RuntimeError(f"no answer to {name} after {i} calls:\n{node.log()}")
            answers[(name, bool(r.success), bool(r.message))] += 1
            if node.proc.poll() is not None:
                raise RuntimeError(f"the node ended after {i + 1} calls:\n{node.log()}")
        answers[("alive", node.proc.poll() is None, True)] += 1
    finally:
        client.close()
        node.stop()
    return answers


def looped_replay(work: Path, sim: Any, dom: int, loops: int) -> tuple[int, int, str]:
    """A recording replayed ``loops`` times with its own stamps (each pass starts again at the first
    stamp: time going back) and one robot pose stamped an hour ahead in the first pass: how many
    captures succeeded of how many, and the node's pose-buffer line."""
    node = NodeProcess("calibration_node", {**PARAMS, "max_views": 100, "record_session": "never"}, dom,
                       work / "looped.log")
    client = RosClient(dom)
    cell = Cell(client, sim.images["ring_a4"], sim.robot_poses)
    t0 = client.node.get_clock().now().nanoseconds
    stored = tried = 0
    try:
        for loop in range(loops):
            cell.shift_ns = t0 - client.node.get_clock().now().nanoseconds  # the pass starts at the first stamp
            for k in range(len(sim.robot_poses)):
                if loop == 0 and k == 1:
                    cell.pose(cell.stamp(3600 * 10**9))  # a pose stamped an hour ahead
                cell.rest(k)
                r = call(client, node, "capture", 15)
                tried += 1
                stored += int(r is not None and r.success)
        r = call(client, node, "calibrate", 180)
        note = r.message[:120] if r is not None else "no answer"
    finally:
        client.close()
        node.stop()
    return stored, tried, note


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--calls", type=int, default=1000)
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--loops", type=int, default=3, help="passes of the looped recording")
    ap.add_argument("--frame-hz", type=float, default=10.0, help="the storm's frame rate")
    ap.add_argument("--parts", default="kills,looped,storm", help="which parts to run (comma-separated)")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    sim = simulate_arm_session(resolve_target("ring_a4"), ArmSpec(mode="eye_in_hand", views=args.views, width=640,
                                                                  height=480, k1=-0.1, seed=3))
    work = Path(tempfile.mkdtemp(prefix="fault_study_"))
    parts = set(args.parts.split(","))
    ok = True
    if "kills" in parts:
        t0 = time.monotonic()
        ref, _ = session_run(work / "uninterrupted", sim, 61, 0, rng)
        got, events = session_run(work / "killed", sim, 62, args.kills, rng)
        print("\n".join(events))
        ok &= ref == got
        print(f"uninterrupted: {ref}\nkilled {len(events)} times and resumed: {got}\nsame result to the printed "
              f"digit: {ref == got} ({time.monotonic() - t0:.0f} s)")
    if "looped" in parts:
        stored, tried, note = looped_replay(work, sim, 64, args.loops)
        ok &= stored == tried
        print(f"a recording looped {args.loops} times (stamps going back) and a pose stamped an hour ahead: {stored} "
              f"of {tried} captures stored; ~/calibrate: {note}")
    if "storm" in parts:
        t1 = time.monotonic()
        answers = service_storm(work, sim, 63, args.calls, rng, args.frame_hz)
        bad = sum(v for (name, _, said), v in answers.items() if not said)
        ok &= bad == 0 and answers[("alive", True, True)] == 1
        print(f"{args.calls} service calls in random order, frames at {args.frame_hz:g} Hz "
              f"({time.monotonic() - t1:.0f} s): "
              + ", ".join(f"{n} {'ok' if good else 'refused'} {v}" for (n, good, _), v in sorted(answers.items()))
              + f"; answers without a message: {bad}")
    return 0 if ok else 1

if __name__ == "__main__":
    raise SystemExit(main())
