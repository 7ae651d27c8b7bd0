"""Where the next view comes from, for the guided-session study (:mod:`.guided_study`): the guide,
random poses, the node's present diversity filter, a plain coverage heuristic and a fixed
checklist, with a simulated person who places the target where asked only approximately.

Every strategy is an object with ``next(state) -> Pose`` (the pose the person is asked for, or
draws), called until the session has enough views; the session renders the view, detects the
target and recalibrates. The person's placement error (:class:`PersonError`) is applied to every
pose a strategy *asks* for (guide, coverage, checklist); random and diversity draw poses
already.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..analysis import (
    Feasibility,
    Placement,
    bootstrap_placements,
    default_feasibility,
    distance_for_size,
    distinct_from_all,
    feasibility_problem,
    feature_centre,
    place,
    suggest_views,
)
from ..calibrate import CalibrationResult
from ..detect import CircleEdge, Detection
from ..geometry import Camera, Transform, fit_conics_algebraic, observed_field_mask
from ..session import ViewCollector, placement_points
from ..sim import Pose, SessionSpec, random_poses
from ..targets import Target


@dataclass(frozen=True)
class PersonError:
    """How far a person misses the pose asked for: the target's centre by ``pixel_frac`` of the
    image width per axis, the distance by ``distance_frac``, the tilt by ``tilt_deg``, its axis
    by ``axis_deg``, the roll by ``roll_deg`` (standard deviations). With ``rotation_deg`` or
    ``position_m`` > 0 the miss is metric instead (:meth:`pose`): the sheet turned by a rotation
    vector of σ ``rotation_deg`` per axis about the features' centre, that centre moved by σ
    ``position_m`` per axis (camera frame)."""

    pixel_frac: float = 0.03
    distance_frac: float = 0.05
    tilt_deg: float = 5.0
    axis_deg: float = 10.0
    roll_deg: float = 5.0
    rotation_deg: float = 0.0
    position_m: float = 0.0

    @property
    def metric(self) -> bool:
        return self.rotation_deg > 0 or self.position_m > 0

    def apply(self, p: Placement, width: int, rng: np.random.Generator) -> Placement:
        """The placement missed (the relative error of the class docstring)."""
        e = rng.normal(size=6)
        return Placement((p.pixel[0] + e[0] * self.pixel_frac * width, p.pixel[1] + e[1] * self.pixel_frac * width),
                         p.distance * float(np.exp(e[2] * self.distance_frac)),
                         abs(p.tilt_deg + e[3] * self.tilt_deg), p.axis_deg + e[4] * self.axis_deg,
                         p.roll_deg + e[5] * self.roll_deg)

    def pose(self, target: Target, cam: Camera, p: Placement, rng: np.random.Generator) -> Transform:
        """camera_T_target of placement ``p`` as the person takes it: relative (:meth:`apply`) or,
        when :attr:`metric`, R' = exp([ω]) R, c' = c + δ with ω ~ N(0, rotation_deg²), δ ~
        N(0, position_m²) per axis, c the features' centre in the camera frame."""
        if not self.metric:
            return place(target, cam, self.apply(p, cam.width, rng))
        T = place(target, cam, p)
        e = rng.normal(size=6)
        dR = Rotation.from_rotvec(np.radians(self.rotation_deg) * e[:3])
        c = T.apply(np.r_[feature_centre(target), 0.0])
        R = dR * T.rotation
        t = c + self.position_m * e[3:] - R.apply(np.r_[feature_centre(target), 0.0])
        return Transform(R, t)


@dataclass
class SessionState:
    """What a strategy may look at: the true camera (to turn placements into poses, as the person's
    eye would), the target, the views so far and the latest calibration."""

    target: Target
    camera: Camera  # ground truth: used only to render what the person does
    dets: list[Detection] = field(default_factory=list)
    calibration: CalibrationResult | None = None
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    sigma_px: float = float("nan")  # the guide's real whole-image sigma after the last calibration


def _fit(target: Target, cam: Camera, p: Placement, rules: Feasibility) -> Placement | None:
    """The placement, or the nearest feasible one: smaller and nearer the image centre."""
    for shrink in (1.0, 0.85, 0.7, 0.55):
        for pull in (0.0, 0.15, 0.3, 0.5):
            u = p.pixel[0] + pull * (cam.width / 2 - p.pixel[0])
            v = p.pixel[1] + pull * (cam.height / 2 - p.pixel[1])
            q = Placement((u, v), p.distance / shrink, p.tilt_deg, p.axis_deg, p.roll_deg)
            if not feasibility_problem(target, cam, place(target, cam, q), rules):
                return q
    return None


def asked(state: SessionState, p: Placement, error: PersonError | None) -> Pose:
    """The pose the person takes when asked for placement ``p`` (made feasible first; the
    person's error applied, retried while it throws the target out of view)."""
    cam, target = state.camera, state.target
    # the person looks at the target's outline, not at its shape: the guide's own rules decide that
    rules = replace(default_feasibility(target, cam.width), shape_share=np.inf)
    q = _fit(target, cam, p, rules) or p
    for _ in range(8):
        T = error.pose(target, cam, q, state.rng) if error is not None else place(target, cam, q)
        if not feasibility_problem(target, cam, T, rules):
            return Pose(T.R, T.translation)
    T = place(target, cam, q)
    return Pose(T.R, T.translation)


class Guided:
    """The guide: fixed bootstrap views, then the best suggestion (:func:`suggest_views`) from the
    latest calibration. A suggestion whose view the detector refused is avoided for the rest of the
    session, as the node's :meth:`..session.guide.GuideState.refuse` does: its placement is passed
    to :func:`suggest_views` as ``avoid`` (no candidate in its neighbourhood is offered) and the
    bootstrap views in its neighbourhood are skipped. ``repeated`` counts suggestions in the
    neighbourhood of a refused one (the guide's promise: 0)."""

    name = "guided"

    def __init__(self, error: PersonError | None, spec: SessionSpec):
        self.error, self.spec = error, spec
        self.boot = 0
        self.failed: list[Placement] = []
        self.last: Placement | None = None
        self.fallbacks = 0  # views of the person's own choosing when the guide had no feasible candidate
        self.repeated = 0
        self.asked: list[dict[str, object]] = []  # what was asked, for the study's record

    def next(self, state: SessionState) -> Pose:
        cal = state.calibration
        self.last = None
        if cal is None or cal.refinement is None or cal.refinement.covariance is None:
            boot = bootstrap_placements(state.camera, state.target)
            order = self._allowed([boot[(self.boot + k) % len(boot)] for k in range(len(boot))], state.camera)
            if not order:
                self.fallbacks += 1
                return RandomPoses(self.spec).next(state)
            self.boot = boot.index(order[0]) + 1
            return self._ask(state, order[0])
        s = suggest_views(cal.refinement, state.target, cal.size, n=4, avoid=self.failed)
        state.sigma_px = s.sigma_px
        if not s.suggestions:  # no feasible candidate: what a person would do, a view of their own
            self.fallbacks += 1
            return RandomPoses(self.spec).next(state)
        return self._ask(state, s.suggestions[0].placement)

    def _allowed(self, ps: list[Placement], cam: Camera) -> list[Placement]:
        """``ps`` without those in the neighbourhood of a refused placement."""
        if not ps or not self.failed:
            return ps
        keep = distinct_from_all(ps, self.failed, cam.size)
        return [p for p, k in zip(ps, keep, strict=True) if k]

    def _ask(self, state: SessionState, p: Placement) -> Pose:
        self.repeated += len(self._allowed([p], state.camera)) == 0
        self.last = p
        self.asked.append({"pixel": [round(p.pixel[0]), round(p.pixel[1])], "distance": round(p.distance, 3),
                           "tilt": round(p.tilt_deg), "axis": round(p.axis_deg), "n": len(state.dets)})
        return asked(state, p, self.error)

    def rejected(self, reason: str = "") -> None:
        if self.last is not None:
            self.failed.append(self.last)
            self.asked[-1]["refused"] = reason


class RandomPoses:
    """Random poses as :func:`..sim.render.random_poses` draws them (the studies' sessions)."""

    name = "random"

    def __init__(self, spec: SessionSpec):
        self.spec = spec

    def next(self, state: SessionState) -> Pose:
        s = self.spec
        return random_poses(state.target, state.camera, 1, state.rng, s.tilt_range, s.size_range,
                            pixel_range=s.pixel_range)[0]

    def rejected(self, reason: str = "") -> None:
        pass


def synthetic_detection(target: Target, cam: Camera, pose: Pose) -> Detection:
    """A detection's edges (points and conics) and board corners drawn from the pose, without
    rendering: what the diversity filter (:class:`..session.collector.ViewCollector`) looks at."""
    a = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    outer = [k for k, c in enumerate(target.circles) if c.dark_inside]
    pts = []
    for k in outer:
        c = target.circles[k]
        xy = np.c_[c.center[0] + c.radius * np.cos(a), c.center[1] + c.radius * np.sin(a), np.zeros(len(a))]
        pts.append(cam.project(xy @ pose.R.T + pose.t))
    edges = []
    if pts:
        owner = np.repeat(np.arange(len(pts)), len(a))
        C, _ = fit_conics_algebraic(np.concatenate(pts), owner, len(pts))
        edges = [CircleEdge(k, p, Ck, 1.0, 0.0) for k, p, Ck in zip(outer, pts, C, strict=True)]
    corners = None
    if target.board is not None:  # a board's corners, those out of the image NaN
        P = target.board.corner_points()
        corners = cam.project(np.c_[P, np.zeros(len(P))] @ pose.R.T + pose.t)
        out = ~((corners >= 0) & (corners <= (cam.width - 1, cam.height - 1))).all(1)
        corners[out] = np.nan
    return Detection(cam.width, cam.height, edges=edges, corners=corners)


class Diversity:
    """The node's present filter: a person waves the target (random poses); a frame is stored when
    :class:`..session.collector.ViewCollector` finds it different enough from those stored."""

    name = "diversity"

    def __init__(self, spec: SessionSpec) -> None:
        self.collector = ViewCollector(min_views=8, max_views=1000)
        self.placed = False
        self.random = RandomPoses(spec)

    def next(self, state: SessionState) -> Pose:
        if not self.placed:
            self.collector.board_points, self.placed = placement_points(state.target), True
        for _ in range(400):
            pose = self.random.next(state)
            ok, _ = self.collector.offer(synthetic_detection(state.target, state.camera, pose))
            if ok:
                return pose
        return pose

    def rejected(self, reason: str = "") -> None:
        pass


class Coverage:
    """A plain coverage heuristic: the next view where the image is least covered (cells of a
    5 x 4 grid by the fraction the views' feature hulls cover), tilted 40 degrees toward that
    edge (the side nearer the border farther away); the first three are the guide's bootstrap
    views."""

    name = "coverage"

    def __init__(self, error: PersonError | None):
        self.error = error
        self.n = 0

    def next(self, state: SessionState) -> Pose:
        cam, target = state.camera, state.target
        if self.n < 3:
            self.n += 1
            return asked(state, bootstrap_placements(cam, target)[self.n - 1], self.error)
        self.n += 1
        pts = [np.concatenate([e.points for e in d.edges] + ([d.corners] if d.corners is not None else []))
               for d in state.dets if d.ok]
        mask = observed_field_mask(pts, cam.size) if pts else np.zeros((cam.height, cam.width), bool)
        cols, rows = 5, 4
        best: tuple[float, float, float, float] | None = None
        for i in range(rows):
            for j in range(cols):
                cell = mask[i * cam.height // rows:(i + 1) * cam.height // rows,
                            j * cam.width // cols:(j + 1) * cam.width // cols]
                u, v = (j + 0.5) * cam.width / cols, (i + 0.5) * cam.height / rows
                off = np.hypot(u - cam.width / 2, v - cam.height / 2)
                key = (float(cell.mean()), -off)
                if best is None or key < best[:2]:
                    best = (*key, u, v)
        assert best is not None
        u, v = best[2], best[3]
        d = np.degrees(np.arctan2(v - cam.height / 2, u - cam.width / 2))
        p = Placement((u, v), distance_for_size(target, cam, 0.45), 40.0, d - 90.0, 0.0)
        return asked(state, p, self.error)

    def rejected(self, reason: str = "") -> None:
        pass


def checklist_placements(cam: Camera, target: Target) -> list[Placement]:
    """A fixed 20-view checklist of the usual advice: the guide's three bootstrap views, the four
    corners and the four edges tilted 40 degrees with the outer side away, the middle head-on and
    close, the corners tilted the other way, the middle tilted 50 degrees about four axes."""
    w, h = cam.width, cam.height
    d4, d6, d35 = (distance_for_size(target, cam, s) for s in (0.4, 0.6, 0.35))
    out = list(bootstrap_placements(cam, target))
    corners = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)]
    edges = [(0.5, 0.2), (0.8, 0.5), (0.5, 0.8), (0.2, 0.5)]

    def outward(fx: float, fy: float) -> float:
        return float(np.degrees(np.arctan2((fy - 0.5) * h, (fx - 0.5) * w))) - 90.0

    out += [Placement((fx * w, fy * h), d4, 40.0, outward(fx, fy), 0.0) for fx, fy in corners + edges]
    out.append(Placement((0.5 * w, 0.5 * h), d6, 0.0, 0.0, 0.0))
    out += [Placement((fx * w, fy * h), d35, 40.0, outward(fx, fy) + 180.0, 15.0) for fx, fy in corners]
    out += [Placement((0.5 * w, 0.5 * h), distance_for_size(target, cam, 0.45), 50.0, a, 0.0)
            for a in (0.0, 90.0, 180.0, 270.0)]
    return out[:20]


class Checklist:
    """:func:`checklist_placements`, in order."""

    name = "checklist"

    def __init__(self, error: PersonError | None):
        self.error = error
        self.n = 0

    def next(self, state: SessionState) -> Pose:
        ps = checklist_placements(state.camera, state.target)
        p = ps[self.n % len(ps)]
        self.n += 1
        return asked(state, p, self.error)

    def rejected(self, reason: str = "") -> None:
        pass


STRATEGIES = ("guided", "random", "diversity", "coverage", "checklist")


def make_strategy(name: str, error: PersonError | None, spec: SessionSpec
                  ) -> Guided | RandomPoses | Diversity | Coverage | Checklist:
    """The strategy of that name; ``spec`` the random sessions' distribution of poses."""
    if name == "guided":
        return Guided(error, spec)
    if name == "random":
        return RandomPoses(spec)
    if name == "diversity":
        return Diversity(spec)
    if name == "coverage":
        return Coverage(error)
    if name == "checklist":
        return Checklist(error)
    raise ValueError(f"unknown strategy {name!r}: {', '.join(STRATEGIES)}")
