"""The guide of a live session (the node's ``guide:=true``), ROS-free and thread-safe: it wraps a
:class:`~.guide.GuideState` for frames that arrive on one thread while the guide's update (a
calibration of the stored views and the ranking of the next ones) runs on another.

- :meth:`GuidedLive.examine` compares each frame's detection with the current suggestion: a usable
  frame is to be stored only when it matches the suggested outline (overlap >= 0.85); the live
  session's stillness gate still applies (:class:`~.live.LiveSession`). A frame that does not
  match gets one hint (position, then distance, then tilt from the live target's pose found with
  the current camera, :func:`live_pose`).
- :meth:`GuidedLive.stored` is called after a view was stored: the update then runs on a worker
  thread (:meth:`GuidedLive.update_now` is its body), frames keep flowing, and nothing is stored
  until the next suggestion is there (the picture says "computing the next view...").
- Done comes from :attr:`GuideState.done`: the real projection sigma of the recalibrated usable
  views (a refused detection is never counted), never a prediction. Once done, no more views are
  stored by the guide (``~/capture`` still can).
- A view refused by the detector at a suggestion (:meth:`GuidedLive.refuse`) makes the guide avoid
  that suggestion's neighbourhood until :meth:`GuidedLive.reset` (:meth:`.guide.GuideState.refuse`)
  and offer the next one. The node calls it for a refused ``~/capture`` (``collect:=on_capture``);
  with ``watch_refusals`` (``collect:=auto``, a person) :meth:`GuidedLive.examine` calls it itself
  when, after a usable frame near the suggestion (overlap >= :data:`NEAR_OVERLAP`), the detector
  refuses :data:`REFUSED_FRAMES` frames in a row: the person holds the target there and it cannot
  be measured.

The first suggestions (bootstrap, fewer than 3 views) are drawn with ``camera_guess``, or with a
nominal camera (focal length = the image width, principal point at the centre) made from the
first frame's size.
"""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ..calibrate import MIN_VIEWS, CalibrationError, CalibrationOptions, IntrinsicStart, calibrate_warm
from ..calibrate.handeye import camera_pose
from ..detect import Detection
from ..geometry import Camera, ImageSize, Transform
from ..targets import Target
from .guide import GuideState, Match

COMPUTING = "computing the next view..."
NEAR_OVERLAP = 0.5  # a usable frame this close to the suggestion: the person is there or nearly
REFUSED_FRAMES = 15  # then this many refused frames in a row: the view at the suggestion is refused


@dataclass(frozen=True)
class GuideVerdict:
    """The guide's word on one frame: store it or not, and the line for the picture."""

    store: bool
    line: str
    match: Match | None


@dataclass(frozen=True)
class GuideView:
    """What the picture and ``~/status`` show of the guide at one moment."""

    outline: np.ndarray = field(repr=False)  # (K, 2) px, the suggested target's outline (empty: none)
    overlap: float
    matched: bool
    hint: str
    sigma_px: float  # real worst projection sigma of the stored views (nan before a calibration)
    goal_sigma_px: float
    done: bool
    computing: bool
    suggestion: str  # the current suggestion in words ("" before the first frame)
    predicted_sigma_px: float
    pose: Transform | None  # the suggestion's camera_T_target (target YAML frame -> camera optical frame)
    index: int
    count: int
    error: str
    update_seconds: float
    refused: str = ""  # the last refusal of a suggestion's view, until the next view is stored
    avoided: int = 0  # suggestions avoided in this session (their views were refused)


def describe(state: GuideState) -> str:
    """The current suggestion in words: where the target's centre goes, distance, tilt, roll."""
    s = state.current
    if s is None:
        return ""
    p = s.placement
    return (f"{state.index + 1}/{len(state.suggestions)}: centre at ({p.pixel[0]:.0f}, {p.pixel[1]:.0f}) px, "
            f"{p.distance:.2f} m, tilt {p.tilt_deg:.0f} deg about {p.axis_deg:.0f} deg, roll {p.roll_deg:.0f} deg")


def live_pose(state: GuideState, det: Detection) -> Transform | None:
    """The live target's pose (camera_T_target; its rotation is the target YAML frame's) from the
    current camera (the calibration, or the guess before one), None when it cannot be found. Only
    its normal is used (the tilt hint): good to a few degrees from one frame."""
    try:
        return camera_pose(det, state.target, state.camera or state.camera_guess, state.target.local_origin)
    except Exception:  # no pose from this frame: the hint says position and distance only
        return None


class GuidedLive:
    """The guide of a live session (module docstring); every method may be called from any thread."""

    def __init__(self, target: Target, options: CalibrationOptions, goal_sigma_px: float = 0.1, n: int = 5,
                 camera_guess: Camera | None = None, watch_refusals: bool = False) -> None:
        if not (np.isfinite(goal_sigma_px) and goal_sigma_px > 0):
            raise ValueError(f"goal_sigma_px {goal_sigma_px}: give a finite value > 0 (px)")
        self.target, self.options, self.n = target, options, int(n)
        self.goal_sigma_px = float(goal_sigma_px)
        self.camera_guess = camera_guess
        self.lock = threading.Lock()
        self.state: GuideState | None = None
        self.size = (0, 0)
        self.computing = False
        self._again: list[Detection] | None = None  # views stored while an update ran: update again
        self.last_match: Match | None = None
        self.error = ""
        self.update_seconds = float("nan")
        self.generation = 0  # counts resets: an update of views from before a reset is thrown away
        self._start: IntrinsicStart | None = None  # the last recalibration, the next one's warm start
        self.watch_refusals = watch_refusals
        self._near = False  # the last usable frame was near the suggestion
        self._refused_frames = 0  # refused frames since then
        self._views: list[Detection] = []  # the stored views of the last update
        self.refused = ""

    def _state(self, size: ImageSize) -> GuideState:
        """The state, made on the first frame (its size gives the nominal camera). Under the lock."""
        width, height = size
        if self.state is None or self.size != (width, height):
            guess = self.camera_guess
            if guess is None or (guess.width, guess.height) != (width, height):
                guess = Camera.from_params(float(width), float(width), width / 2.0, height / 2.0, width=width,
                                           height=height)
            self.state = GuideState(self.target, guess, self.goal_sigma_px, self.n)
            self.size = (width, height)
        return self.state

    def examine(self, det: Detection) -> GuideVerdict:
        """Whether this frame's detection is to be stored (it matches the suggestion) and the line."""
        with self.lock:
            state = self._state(det.size)
            if self.computing:
                self.last_match = None
                return GuideVerdict(False, COMPUTING, None)
            if state.done:
                return GuideVerdict(False, f"DONE: sigma {state.sigma_px:.3f} px <= goal {state.goal_sigma_px:g} px; "
                                           "call ~/calibrate", None)
            m = state.match(det)
            refused = self._watch(det, m) if self.watch_refusals else ""
            if refused:
                return GuideVerdict(False, refused, None)
            if not m.matched and det.ok:  # the tilt hint needs the live target's pose
                live = live_pose(state, det)
                if live is not None:
                    m = state.match(det, live)
            self.last_match = m
        if m.matched:
            return GuideVerdict(True, f"match {m.overlap:.2f}: {m.hint}", m)
        return GuideVerdict(False, f"match {m.overlap:.2f}: {m.hint}", m)

    def _watch(self, det: Detection, m: Match) -> str:
        """The refusal heuristic of ``collect:=auto`` (module docstring); under the lock. Returns
        the refusal's line when this frame completes one."""
        if det.ok:
            self._near, self._refused_frames = m.overlap >= NEAR_OVERLAP, 0
            return ""
        if not self._near or not det.reason:
            return ""
        self._refused_frames += 1
        if self._refused_frames < REFUSED_FRAMES:
            return ""
        return self._refuse_locked(det.reason)

    def _refuse_locked(self, reason: str) -> str:
        assert self.state is not None
        line = self.state.refuse(reason)
        self._near, self._refused_frames, self.last_match = False, 0, None
        if line:
            self.refused = line
        if line and not self.state.suggestions and not self.computing and self._views:
            self.computing = True  # none left: rank again, the refused neighbourhoods left out
            threading.Thread(target=self._run, args=(list(self._views), self.generation), name="guide-update",
                             daemon=True).start()
        return line

    def refuse(self, reason: str) -> str:
        """The view taken at the current suggestion was refused by the detector (``reason``): its
        neighbourhood is not suggested again until :meth:`reset`; returns the line that says so
        ("" without a suggestion)."""
        with self.lock:
            if self.state is None:
                return ""
            return self._refuse_locked(reason)

    def stored(self, views: list[Detection]) -> bool:
        """A view was stored (``views``: all stored views now): update the guide on a worker thread.
        Returns False when an update already runs (it is repeated with these views when it ends)."""
        with self.lock:
            self._views, self.refused = list(views), ""
            if self.computing:
                self._again = list(views)
                return False
            self.computing = True
            generation = self.generation
        threading.Thread(target=self._run, args=(list(views), generation), name="guide-update", daemon=True).start()
        return True

    def _run(self, views: list[Detection], generation: int) -> None:
        try:
            while True:
                self.update_now(views, generation)
                with self.lock:
                    again, self._again = self._again, None
                    if again is None or generation != self.generation:
                        return
                views = again
        except Exception as e:  # never leave the guide "computing" for ever
            with self.lock:
                self.error = f"guide update failed: {type(e).__name__}: {e}"
        finally:
            with self.lock:
                if generation == self.generation:
                    self.computing = False

    def update_now(self, views: list[Detection], generation: int | None = None) -> None:
        """Recalibrate ``views`` and rank the next suggestions (the worker's body; blocking). The
        state is updated on a copy and swapped in, so that frames are matched meanwhile."""
        t0 = time.perf_counter()
        ok = [d for d in views if d.ok]
        with self.lock:
            if self.state is None:
                if not ok:
                    return
                self._state(ok[0].size)
            assert self.state is not None
            work, start = copy.copy(self.state), self._start
        error, refinement = "", None
        if len(ok) >= MIN_VIEWS:
            try:
                with threadpool_limits(1, "blas"):  # small dense products: one thread is faster on a shared machine
                    # warm from the last recalibration when the views only grew (calibrate/intrinsic/warm.py: the
                    # cold result to the solver's tolerance), cold otherwise
                    result, start = calibrate_warm(ok, self.target, self.options, start)
                refinement = result.refinement
                if refinement is None or refinement.covariance is None:
                    error = "the calibration has no covariance to predict from; showing a fixed view"
            except CalibrationError as e:
                error = f"the views do not calibrate yet ({e}); showing a fixed view"
            except Exception as e:  # a numerical failure must not stop the guide
                error = f"calibration failed ({type(e).__name__}: {e}); showing a fixed view"
        try:
            with threadpool_limits(1, "blas"):
                work.update(refinement, ImageSize(self.size[0], self.size[1]), len(ok))
        except Exception as e:  # a numerical failure must not stop the guide: keep the last suggestions
            error = f"guide update failed: {type(e).__name__}: {e}"
            work = self.state
        with self.lock:
            if generation is not None and generation != self.generation:
                return
            if work is not self.state:  # a refusal while this ran: its neighbourhood is left out too
                work.avoided, work.refusals = self.state.avoided, self.state.refusals
                work.suggestions = work._allowed(work.suggestions)
                work.index = min(work.index, max(len(work.suggestions) - 1, 0))
            self.state, self.error, self._start = work, error, start
            self.update_seconds = time.perf_counter() - t0

    def skip(self) -> str:
        """Move on to the next suggestion; returns it in words (empty before the first frame)."""
        with self.lock:
            if self.state is None:
                return ""
            self.state.skip()
            self.last_match = None
            return describe(self.state)

    def reset(self) -> None:
        """Forget the guide's progress (the session's views were cleared)."""
        with self.lock:
            self.generation += 1
            self.state, self.size, self.computing, self._again = None, (0, 0), False, None
            self.last_match, self.error, self._start = None, "", None
            self._views, self.refused, self._near, self._refused_frames = [], "", False, 0

    def view(self) -> GuideView:
        """The guide now, for the picture and ``~/status``."""
        with self.lock:
            s, m = self.state, self.last_match
            outline = s.outline() if s is not None and not self.computing else np.zeros((0, 2))
            cur = s.current if s is not None else None
            return GuideView(outline=outline, overlap=m.overlap if m else 0.0, matched=bool(m and m.matched),
                             hint=COMPUTING if self.computing else (m.hint if m else ""),
                             sigma_px=s.sigma_px if s is not None else float("nan"),
                             goal_sigma_px=self.goal_sigma_px, done=bool(s is not None and s.done),
                             computing=self.computing, suggestion=describe(s) if s is not None else "",
                             predicted_sigma_px=cur.predicted_sigma_px if cur is not None else float("nan"),
                             pose=cur.pose if cur is not None else None,
                             index=s.index if s is not None else 0, count=len(s.suggestions) if s is not None else 0,
                             error=self.error, update_seconds=self.update_seconds, refused=self.refused,
                             avoided=len(s.avoided) if s is not None else 0)

    def set_goal(self, goal_sigma_px: float) -> None:
        """Change the goal at run time (done follows at once from the last real sigma)."""
        with self.lock:
            self.goal_sigma_px = float(goal_sigma_px)
            if self.state is not None:
                self.state.goal_sigma_px = self.goal_sigma_px
