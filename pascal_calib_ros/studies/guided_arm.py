"""The arm case of ``pascal-calib study guided``: an eye-in-hand session on renders, the arm
accurate to 0.1 mm / 0.01 deg per axis and pose (no systematic error), where coverage alone
cannot tell which pose matters: the hand-eye rotation needs the motions' rotation axes spread.

Strategies (the tool pose commanded; the arm reaches it and reports it with its noise):

- ``guided``: the first three views of ``designed``, then the guide's best tool pose
  (:func:`..analysis.arm_guidance.suggest_arm_views`, a trust region of 0.3 m and 120 degrees
  around the visited poses; a suggested view the detector refuses is not asked for again, as the
  node's ``avoid``); :data:`GUIDE_VARIANTS` are the guide's variants of issue 36 and
  :data:`ARM_CELLS` the cells (``pascal-calib study guided --arm-guide``, ``--arm-cell``);
- ``designed``: 20 views laid out on purpose: the target's centre on a 3 x 3 grid of the image,
  tilted 35 degrees about eight evenly spread axes, rolled about the optical axis by the golden
  angle from view to view (every motion's rotation axis different); ``designed`` at N is this
  set cut at N;
- ``random``: the views of the hand-eye study's sessions (:func:`..sim.arm.arm_poses`: tilts of
  15-45 degrees about random axes, rolls within +-30 degrees);
- ``easy_handeye``: easy_handeye's automatic 17 poses around a start pose (the tool turned by
  +-25 and +-12.5 degrees about its own x, y and z axes, then moved by +-5 cm along the base's x,
  +-10 cm along y and +3.3 cm along z; github IFL-CAMP/easy_handeye, handeye_robot.py), the
  start pose looking at the target head-on from the middle of the image; a pose whose view
  loses the target is lost, as on a real cell.

Per strategy and N (6, 8, 10, 12, 14, 17, 20 views used): X's true rotation and translation error,
fx's error and the true projection error over the whole image (as :mod:`.guided_study`).

One session's error is one draw of the image and arm noise: its norm over three axes spreads by
about 40 %, so a median over 20 seeds moves by 10-15 % and a ratio of two by more. With
``draws`` > 0 each session's views (the tool poses commanded, as the strategy chose them) are
shot again under that many fresh draws of the image and arm noise and calibrated at N = 8, 12, 20
(:func:`redraw_session`): the error the strategy's *views* give, averaged over the noise, pooled
over the seeds as an RMS (``guided_arm_redraws.jsonl``).
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ..analysis import (
    DETECTOR_BIAS,
    DISTINCT_ROLL_DEG,
    ArmGoals,
    ArmRanking,
    ArmSuggestion,
    DetectorBias,
    Linearisation,
    Placement,
    TrustRegion,
    ViewPredictor,
    arm_model,
    distance_for_size,
    distinct_from_all,
    place,
    suggest_arm_views,
)
from ..calibrate import CalibrationError
from ..calibrate.handeye import HandEyeOptions, HandEyeResult, calibrate_hand_eye
from ..detect import detect_target
from ..geometry import Transform
from ..modes import HandEyeMode
from ..sim import DEFAULT_HAND_EYE, DEFAULT_TARGET, ArmSpec, Pose, SensorModel, arm_poses, hand_eye_errors, render_view
from ..targets import Target, resolve_target
from .guided_errors import true_errors

ARM_N = (6, 8, 10, 12, 14, 17, 20)
ARM_STRATEGIES = ("guided", "designed", "random", "easy_handeye")
REDRAW_N = (8, 12, 20)
REDRAW_STRATEGIES = ("guided", "designed", "random")  # easy_handeye's X is off by degrees: nothing to average
MODE = HandEyeMode.EYE_IN_HAND
# what the guide is asked for (it ranks by (sigma / goal)^2 summed over the three; the projection goal
# below what the designed 20 views give in the image's corners, X's below their 0.0133 deg / 0.085 mm in
# the guide's model). Asking for those sigmas instead weighted the ranking toward the translation and
# gave X's rotation 1.30x the designed 20's at 12 views (1.17x with these; both before the 35 degree
# candidates: docs/guided-sessions.md)
GUIDED_GOALS = ArmGoals(0.05, 0.005, 0.05)
NO_JACKKNIFE = HandEyeOptions(mode=MODE, jackknife_groups=0)  # the redraws need X, not its sigma (the same X)


@dataclass(frozen=True)
class CellNoise:
    """The cell's noise levels: the renders' sensor noise (grey levels) and the arm's per axis and
    pose. The default is the study's cell; an arm-dominated cell (issue 36: X's rotation error set
    by the arm's share) is e.g. ``CellNoise(0.5, 0.03, 0.3)``."""

    sensor_noise: float = 1.5
    noise_deg: float = 0.01
    noise_mm: float = 0.1

    def spec(self, seed: int, quick: bool) -> ArmSpec:
        """The cell's :class:`..sim.arm.ArmSpec` (no systematic arm error)."""
        return ArmSpec(mode=MODE, width=640 if quick else 800, height=480 if quick else 600, k1=-0.1, seed=seed,
                       systematic_mm=0.0, sensor_noise=self.sensor_noise, noise_deg=self.noise_deg,
                       noise_mm=self.noise_mm)


@dataclass(frozen=True)
class GuideModel:
    """How the guide's model treats the images (:func:`..analysis.arm_guidance.arm_model`): the
    detector's bias (None: none) and whether the image rows keep the refinement's kappa. The
    default is the shipped guide; issue 36's variants are :data:`GUIDE_VARIANTS`, e.g.
    ``GuideModel(DETECTOR_BIAS)`` (kappa kept, the bias added), ``GuideModel(DETECTOR_BIAS, False)``
    (kappa out) and the ranking's options (:class:`..analysis.arm_guidance.ArmRanking`)."""

    bias: DetectorBias | None = None
    keep_kappa: bool = True
    ranking: ArmRanking = ArmRanking()  # noqa: RUF009 (frozen dataclass): the ranking's options


ARM_CELLS = {"study": CellNoise(), "arm": CellNoise(0.5, 0.03, 0.3)}  # pascal-calib study guided --arm-cell
# pascal-calib study guided --arm-guide: the shipped guide and issue 36's variants (docs/guided-sessions.md)
# ("narrow": the guide before the wide turns, which the second study's variants were measured with)
_NARROW = ArmRanking(wide_turns=False)
GUIDE_VARIANTS = {"shipped": GuideModel(), "narrow": GuideModel(ranking=_NARROW),
                  "bias": GuideModel(DETECTOR_BIAS, ranking=_NARROW),
                  "bias-no-kappa": GuideModel(DETECTOR_BIAS, False, _NARROW),
                  "spread": GuideModel(ranking=ArmRanking(spread_weight=1.0, wide_turns=False)),
                  "wide": GuideModel(ranking=ArmRanking(wide_views=10)),
                  "wide-spread": GuideModel(ranking=ArmRanking(spread_weight=1.0, wide_views=10))}


def designed_views(target: Target, spec: ArmSpec) -> list[Transform]:
    """The ``designed`` camera poses (module docstring), camera_T_target."""
    cam = spec.camera()
    d = distance_for_size(target, cam, 0.45)
    grid = [(u, v) for v in (0.35, 0.5, 0.65) for u in (0.35, 0.5, 0.65)]
    out = []
    for k in range(20):
        u, v = grid[(4 * k) % 9]
        p = Placement((u * cam.width, v * cam.height), d, 35.0 if k % 5 else 20.0, 45.0 * (k % 8), 137.5 * k)
        out.append(place(target, cam, p))
    return out


def easy_handeye_tools(start: Transform, angle_deg: float = 25.0, translation: float = 0.1) -> list[Transform]:
    """easy_handeye's 17 tool poses around ``start`` (T_base_tool; module docstring)."""
    out = []
    for scale in (1.0, 0.5):
        for axis in np.eye(3):
            for sgn in (1.0, -1.0):
                turn = Transform.from_rotvec(sgn * scale * np.radians(angle_deg) * axis)
                out.append(Transform(start.rotation * turn.rotation, start.translation))
    for dx in ((translation / 2, 0, 0), (-translation / 2, 0, 0), (0, translation, 0), (0, -translation, 0),
               (0, 0, translation / 3)):
        out.append(Transform(start.rotation, start.translation + np.array(dx)))
    return out


class ArmCell:
    """The simulated cell: true X and Y, the camera, the arm's noise; renders the view of a tool
    pose and reports the pose as the arm would. The image noise differs from session to session
    (seeded by the session's seed and the shot), as the arm's noise does."""

    def __init__(self, target: Target, spec: ArmSpec, seed: int):
        self.target, self.spec = target, spec
        self.X, self.Y = DEFAULT_HAND_EYE[MODE], DEFAULT_TARGET[MODE]
        self.camera = spec.camera()
        self.rng = np.random.default_rng([seed, 77])
        self.seed, self.shots = seed, 0

    def tool_of(self, camera_T_target: Transform) -> Transform:
        return self.Y @ camera_T_target.inverse() @ self.X.inverse()

    def shoot(self, tool: Transform) -> tuple[Any, Transform]:
        """(detection, reported tool pose) of the view at ``tool``."""
        C = self.X.inverse() @ tool.inverse() @ self.Y
        self.shots += 1
        img = render_view(self.target, self.camera, Pose(C.R, C.translation),
                          SensorModel(blur_sigma=self.spec.blur, noise_sigma=self.spec.sensor_noise,
                                      gamma=self.spec.gamma, seed=1000 * self.seed + self.shots)).image
        noise = Transform.from_rotvec(self.rng.normal(0, np.radians(self.spec.noise_deg), 3),
                                      self.rng.normal(0, self.spec.noise_mm / 1000, 3))
        return detect_target(img, self.target, name=f"v{self.shots:02d}.png"), tool @ noise


def _evaluate(cell: ArmCell, dets: list[Any], tools: list[Transform], he: HandEyeOptions | None = None
              ) -> tuple[dict[str, Any], HandEyeResult | None]:
    try:
        h = calibrate_hand_eye(dets, tools, cell.target, MODE, he=he)
    except CalibrationError as e:
        return {"failed": str(e), "rot_err_deg": np.inf, "trans_err_mm": np.inf}, None
    e_mm, e_deg, dt, dr = hand_eye_errors(h.hand_eye, cell.X)
    cal = h.calibration
    rms, worst, _, _ = true_errors(cell.camera, cal.K, cal.D, cal.model)
    return {"rot_err_deg": e_deg, "trans_err_mm": e_mm, "sigma_deg": float(np.linalg.norm(h.rotation_std_deg)),
            "sigma_mm": float(np.linalg.norm(h.translation_std_mm)), "fx_err_pct": 100 * (cal.K[0, 0] /
                                                                                          cell.camera.K[0, 0] - 1),
            "proj_rms_px": rms, "proj_worst_px": worst, "used": h.views_used,
            "rot_err_axes_deg": [float(v) for v in dr], "trans_err_axes_mm": [float(v) for v in dt],
            "pp_err_px": [float(cal.K[0, 2] - cell.camera.K[0, 2]), float(cal.K[1, 2] - cell.camera.K[1, 2])]}, h


def _plan(strategy: str, cell: ArmCell, seed: int) -> list[Transform]:
    """The tool poses of a non-guided strategy, in order."""
    spec = cell.spec
    if strategy == "designed":
        return [cell.tool_of(C) for C in designed_views(cell.target, spec)]
    if strategy == "random":
        s = arm_poses(ArmSpec(mode=MODE, views=20, width=spec.width, height=spec.height, k1=spec.k1, seed=seed,
                              systematic_mm=0.0), cell.target, cell.X, cell.Y)
        return s.robot_poses_true
    if strategy == "easy_handeye":
        cam = cell.camera
        start = place(cell.target, cam, Placement((cam.width / 2, cam.height / 2),
                                                  distance_for_size(cell.target, cam, 0.45), 0.0, 0.0, 0.0))
        t0 = cell.tool_of(start)
        return [t0, *easy_handeye_tools(t0)]
    raise ValueError(strategy)


def run_arm_session(strategy: str, seed: int, target_name: str = "ring_grid_a4", quick: bool = False,
                    n_max: int = 20, noise: CellNoise = CellNoise(), guide: GuideModel = GuideModel()
                    ) -> dict[str, Any]:
    """One arm session (module docstring) in the cell ``noise``, the guide's model ``guide``."""
    target = resolve_target(target_name)
    spec = noise.spec(seed, quick)
    cell = ArmCell(target, spec, seed)
    dets: list[Any] = []
    tools: list[Transform] = []
    commanded: list[Transform] = []  # the tool poses of the usable views, as the strategy asked for them
    curve: dict[str, Any] = {}
    t_start = time.perf_counter()
    plan = _plan(strategy if strategy != "guided" else "designed", cell, seed)
    k = 0
    h: HandEyeResult | None = None
    refused: list[Placement] = []  # suggested views the detector refused since the last usable one
    while len(dets) < n_max and cell.shots < 2 * n_max:
        asked: Placement | None = None  # the guide's view, if it chose this one
        if strategy != "guided" or len(dets) < 3:
            if k >= len(plan):
                break
            tool = plan[k]
            k += 1
        else:
            suggested = _guided_next(h, tools, target, spec, guide, refused)
            if suggested is None:
                break
            tool, asked = suggested.tool, suggested.view.placement
        det, reported = cell.shoot(tool)
        if not det.ok:
            if asked is not None:
                refused.append(asked)
            continue
        refused = []
        dets.append(det)
        tools.append(reported)
        commanded.append(tool)
        n = len(dets)
        if n >= 3 and (strategy == "guided" or n in ARM_N):
            figures, h = _evaluate(cell, dets, tools)
            if n in ARM_N:
                curve[str(n)] = figures
    return {"strategy": strategy, "seed": seed, "target": target_name, "curve": curve, "shots": cell.shots,
            "views": len(dets), "seconds": time.perf_counter() - t_start,
            "commanded": [[*t.translation, *t.quat] for t in commanded], "noise": asdict(noise)}


def redraw_session(row: dict[str, Any], draws: int, quick: bool = False) -> dict[str, Any]:
    """The session's commanded tool poses shot again under ``draws`` fresh draws of the image and
    arm noise (cells seeded apart from every session's), calibrated at each N of
    :data:`REDRAW_N` on the first N usable views: per N the figures of each draw."""
    target = resolve_target(row["target"])
    seed = int(row["seed"])
    spec = CellNoise(**row.get("noise", {})).spec(seed, quick)
    poses = [Transform.from_quat(c[3:], c[:3]) for c in row["commanded"]]
    out: dict[str, list[dict[str, Any]]] = {str(n): [] for n in REDRAW_N if n <= len(poses)}
    for d in range(draws):
        cell = ArmCell(target, spec, 10_000 * (d + 1) + seed)
        dets, tools = [], []
        for tool in poses:
            det, reported = cell.shoot(tool)
            if det.ok:
                dets.append(det)
                tools.append(reported)
        for key in out:
            n = int(key)
            if len(dets) >= n:
                out[key].append(_evaluate(cell, dets[:n], tools[:n], NO_JACKKNIFE)[0])
    return {"strategy": row["strategy"], "seed": seed, "draws": draws, "redraw": out}


def _guided_next(h: HandEyeResult | None, tools: list[Transform], target: Target, spec: ArmSpec,
                 guide: GuideModel, refused: list[Placement]) -> ArmSuggestion | None:
    """The guide's best suggestion from the latest hand-eye calibration (None: none), none near a
    ``refused`` view (as the node's ``avoid``, :func:`..workflows.suggest.suggest_for_arm`: a view
    the detector refused is not asked for again)."""
    if h is None or h.calibration.refinement is None:
        return None
    used = [i for i, v in enumerate(h.per_view) if v.used]
    ref = h.calibration.refinement
    noise = ViewPredictor(Linearisation.of_refinement(ref), spec.size).noise
    model = arm_model(h, [tools[i] for i in used], target, noise, spec.size, bias=guide.bias,
                      keep_kappa=guide.keep_kappa)
    s = suggest_arm_views(model, target, TrustRegion(tuple(tools)), n=1 + 3 * len(refused), goals=GUIDED_GOALS,
                          ranking=guide.ranking)
    kept = s.suggestions
    if refused and kept:
        new = distinct_from_all([a.view.placement for a in kept], refused, spec.size, DISTINCT_ROLL_DEG)
        kept = [a for a, keep in zip(kept, new, strict=True) if keep]
    return kept[0] if kept else None


def _task(args: tuple[str, int, str, bool, int, CellNoise, GuideModel]) -> dict[str, Any]:
    with threadpool_limits(1, "blas"):
        return run_arm_session(*args)


def _redraw_task(args: tuple[dict[str, Any], int, bool]) -> dict[str, Any]:
    with threadpool_limits(1, "blas"):
        return redraw_session(*args)


def _rms(v: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(v)))) if v else float("nan")


def _ratio(a: dict[int, list[float]], b: dict[int, list[float]], rng: np.random.Generator) -> str:
    """RMS of ``a`` over RMS of ``b`` over the seeds both have, and its 90 % interval from 400
    bootstrap resamples of those seeds."""
    both = [s for s in a if a[s] and b.get(s)]
    if not both:
        return ""

    def ratio(seeds: Any) -> float:
        return _rms([x for s in seeds for x in a[s]]) / _rms([x for s in seeds for x in b[s]])

    boot = [ratio(rng.choice(both, len(both))) for _ in range(400)]
    return f"{ratio(both):.2f} ({np.percentile(boot, 5):.2f}-{np.percentile(boot, 95):.2f})"


def summarise_redraws(rows: list[dict[str, Any]]) -> str:
    """Markdown table of the re-drawn sessions: per strategy and N the RMS over every draw of every
    seed, and the ratio to the designed 20 views' with a 90 % bootstrap interval over the seeds."""
    if not rows:
        return ""
    draws = rows[0]["draws"]
    lines = [f"\n### arm: the strategies' views under {draws} fresh noise draws each (RMS over seeds and draws)",
             "", "| strategy | seeds | N | X rotation (deg) | X translation (mm) | fx (%) | projection RMS (px) | "
             "rotation / designed 20 | translation / designed 20 |", "|---|---|---|---|---|---|---|---|---|"]
    rng = np.random.default_rng(0)

    def per_seed(st: str, n: int, key: str) -> dict[int, list[float]]:
        return {r["seed"]: [abs(f[key]) for f in r["redraw"].get(str(n), []) if "failed" not in f]
                for r in rows if r["strategy"] == st}

    ref = {k: per_seed("designed", 20, k) for k in ("rot_err_deg", "trans_err_mm")}
    for st in REDRAW_STRATEGIES:
        for n in REDRAW_N:
            cols = {k: per_seed(st, n, k) for k in ("rot_err_deg", "trans_err_mm", "fx_err_pct", "proj_rms_px")}
            seeds = sorted(s for s, v in cols["rot_err_deg"].items() if v)
            if not seeds:
                continue
            pooled = {k: _rms([x for s in seeds for x in c[s]]) for k, c in cols.items()}
            ratios = [_ratio(cols[k], ref[k], rng) for k in ("rot_err_deg", "trans_err_mm")]
            lines.append(f"| {st} | {len(seeds)} | {n} | {pooled['rot_err_deg']:.4f} | {pooled['trans_err_mm']:.3f} | "
                         f"{pooled['fx_err_pct']:.4f} | {pooled['proj_rms_px']:.3f} | {ratios[0]} | {ratios[1]} |")
    return "\n".join(lines)


def summarise_arm(rows: list[dict[str, Any]]) -> str:
    """Markdown table: medians over the seeds of X's errors and fx's at each N."""
    lines = ["\n### arm, eye in hand (0.1 mm / 0.01 deg arm, no systematic error): medians over the seeds",
             "", "| strategy | seeds | N | X rotation error (deg) | X translation error (mm) | fx error (%) | "
             "projection RMS (px) |", "|---|---|---|---|---|---|---|"]
    for st in ARM_STRATEGIES:
        sr = [r for r in rows if r["strategy"] == st]
        if not sr:
            continue
        for n in ARM_N:
            vals = [r["curve"].get(str(n)) for r in sr]
            got = [v for v in vals if v is not None and "failed" not in v]
            if not got:
                continue
            lines.append(f"| {st} | {len(got)}/{len(sr)} | {n} | {np.median([v['rot_err_deg'] for v in got]):.4f} | "
                         f"{np.median([v['trans_err_mm'] for v in got]):.3f} | "
                         f"{np.median([abs(v['fx_err_pct']) for v in got]):.4f} | "
                         f"{np.median([v['proj_rms_px'] for v in got]):.3f} |")
    return "\n".join(lines)


def run_arm_study(out: Path, seeds: int, quick: bool, jobs: int, target_name: str = "ring_grid_a4",
                  draws: int = 0, noise: CellNoise = CellNoise(),
                  strategies: tuple[str, ...] = ARM_STRATEGIES, n_max: int = 20, guide: GuideModel = GuideModel()
                  ) -> str:
    """Run the arm sessions (resumable: ``guided_arm_sessions.jsonl``), then with ``draws`` their
    views again under fresh noise (``guided_arm_redraws.jsonl``); the tables. ``noise``: the cell's
    noise levels; ``strategies`` and ``n_max`` (views per session) to run less; ``guide`` the guided
    sessions' model (:class:`GuideModel`)."""
    import multiprocessing as mp

    part = out / "guided_arm_sessions.jsonl"
    rows = [json.loads(line) for line in part.read_text().splitlines()] if part.exists() else []
    have = {(r["strategy"], r["seed"]) for r in rows}
    todo = [(st, seed, target_name, quick, n_max, noise, guide) for seed in range(1, seeds + 1) for st in strategies
            if (st, seed) not in have]
    t0 = time.perf_counter()
    sys.stderr.write(f"arm study: {len(todo)} sessions to run ({len(rows)} kept)\n")
    with open(part, "a") as f, mp.get_context("fork").Pool(jobs) as pool:
        for k, r in enumerate(pool.imap_unordered(_task, todo), 1):
            rows.append(r)
            f.write(json.dumps(r) + "\n")
            f.flush()
            c12 = r["curve"].get("12", {})
            sys.stderr.write(f"[{k}/{len(todo)}] arm {r['strategy']} seed {r['seed']}: {r['views']} views of "
                             f"{r['shots']} shots, X at 12: {c12.get('rot_err_deg', float('nan')):.4f} deg "
                             f"{c12.get('trans_err_mm', float('nan')):.3f} mm, {r['seconds']:.0f} s "
                             f"(elapsed {time.perf_counter() - t0:.0f} s)\n")
    return summarise_arm(rows) + (_run_redraws(out, rows, draws, quick, jobs) if draws > 0 else "")


def _run_redraws(out: Path, rows: list[dict[str, Any]], draws: int, quick: bool, jobs: int) -> str:
    """:func:`redraw_session` of every session with its commanded poses (resumable); the table."""
    import multiprocessing as mp

    part = out / "guided_arm_redraws.jsonl"
    done = [json.loads(line) for line in part.read_text().splitlines()] if part.exists() else []
    done = [r for r in done if r["draws"] == draws]
    have = {(r["strategy"], r["seed"]) for r in done}
    todo = [(r, draws, quick) for r in rows if r["strategy"] in REDRAW_STRATEGIES and r.get("commanded")
            and (r["strategy"], r["seed"]) not in have]
    sys.stderr.write(f"arm redraws: {len(todo)} sessions x {draws} draws to run ({len(done)} kept)\n")
    t0 = time.perf_counter()
    with open(part, "a") as f, mp.get_context("fork").Pool(jobs) as pool:
        for k, r in enumerate(pool.imap_unordered(_redraw_task, todo), 1):
            done.append(r)
            f.write(json.dumps(r) + "\n")
            f.flush()
            sys.stderr.write(f"[{k}/{len(todo)}] redraw {r['strategy']} seed {r['seed']} "
                             f"(elapsed {time.perf_counter() - t0:.0f} s)\n")
    return summarise_redraws(done)
