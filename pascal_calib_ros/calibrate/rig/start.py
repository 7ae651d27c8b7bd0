"""The start of a rig's joint refinement: which cameras are connected, a consistent labelling of
symmetric targets, each camera's extrinsic from the median of its per-shot relative poses.

- **Connectivity.** Two cameras are connected when a shot has a posed view in both; the rig is
  connected when every camera reaches camera 0 through such links, transitively (A sees with B,
  B with C). Otherwise no shot ties the groups' frames together and the rig is refused, naming
  the groups (:class:`RigConnectivityError`).
- **Labelling.** A target that looks the same turned (a ring grid by 180 degrees) may be labelled
  turned in one camera's view of a shot and not in the other's, and a grid seen in part is
  labelled up to a shift by whole pitches (``detect/grids.py``: any labelling that fits the
  lattice is exact for one view). The shot's views then claim target poses a turn or a pitch
  apart, and a joint fit that keeps both drags the rig transform off. Cameras are placed in order
  of their links to the cameras already placed (a spanning tree from camera 0). For the next
  camera c every shot it shares with a placed camera p gives, for every symmetry T of the target
  (:func:`~.handeye.target_symmetries`), a candidate extrinsic E_c = C_cs T S_s^-1 with
  S_s = E_p^-1 C_ps L_ps the shot pose that p's labelled view implies. The candidate that most
  shots agree with (rotation within ``tolerance_deg``, translation within ``tolerance_rel`` of the
  target's distance) is the consensus, and the median of the agreeing candidates E_c's start:
  per component of the rotation vectors relative to the consensus, and of the translations.
  Then each of c's views is labelled by the move that best aligns it with its shot:
  L_cs = snap(C_cs^-1 E_c S_s), the nearest symmetry of the target, or for a single grid the
  nearest lattice move (a turn by a multiple of 90 degrees and a shift by whole pitches); a view
  that no move aligns within the tolerances is left out with the reason (the target moved
  between the exposures, or a wrong detection).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ...geometry import Transform
from ..intrinsic.result import CalibrationError


class RigConnectivityError(CalibrationError):
    """The rig's cameras fall into groups that no shot connects."""


@dataclass
class RigStart:
    """Extrinsics (camera 0 -> camera c, X_c = R X_0 + t; [0] the identity), the labelling turn
    of every posed view (key (camera, shot)), views left out with their reason, and the order in
    which the cameras were placed with the camera each was placed from (-1 for camera 0)."""

    extrinsics: list[Transform]
    labels: dict[tuple[int, int], Transform]
    dropped: dict[tuple[int, int], str] = field(default_factory=dict)
    parent: dict[int, int] = field(default_factory=dict)
    shared: dict[int, int] = field(default_factory=dict)  # camera -> shots it shared with the placed cameras


def camera_groups(posed: dict[tuple[int, int], Transform], n_cameras: int) -> list[list[int]]:
    """Connected groups of cameras (sorted, the group of camera 0 first) of the posed views
    (key (camera, shot)): cameras are linked by a shot both have a view of."""
    parent = list(range(n_cameras))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    by_shot: dict[int, list[int]] = {}
    for c, s in posed:
        by_shot.setdefault(s, []).append(c)
    for cams in by_shot.values():
        for c in cams[1:]:
            parent[root(c)] = root(cams[0])
    groups: dict[int, list[int]] = {}
    for c in range(n_cameras):
        groups.setdefault(root(c), []).append(c)
    return sorted(groups.values(), key=lambda g: (0 not in g, g[0]))


def check_connected(posed: dict[tuple[int, int], Transform], names: list[str]) -> None:
    """A :class:`RigConnectivityError` naming the groups if the cameras are not connected."""
    groups = camera_groups(posed, len(names))
    if len(groups) == 1:
        return
    shots_of = {c: sorted(s for cc, s in posed if cc == c) for c in range(len(names))}
    desc = "; ".join("{" + ", ".join(names[c] for c in g) + "}" for g in groups)
    lonely = [names[c] for c in range(len(names)) if not shots_of[c]]
    extra = f" ({', '.join(lonely)} had no usable view)" if lonely else ""
    raise RigConnectivityError(f"the rig's cameras are not connected through shared shots: groups {desc}{extra}; "
                               "take shots in which a camera of one group and a camera of another both see the "
                               "whole target")


def rotation_distance_deg(a: Rotation, b: Rotation) -> float:
    return float(np.degrees((a * b.inv()).magnitude()))


@dataclass(frozen=True)
class LabelMoves:
    """The relabellings a view may need: the target's symmetries (identity first) and, for a
    target that is a single grid, the grid's ``pitch`` (any lattice move then)."""

    symmetries: list[Transform]
    pitch: float = 0.0

    def nearest(self, T: Transform) -> Transform:
        """The allowed move nearest to T (a transform of the target's local frame)."""
        if self.pitch > 0:
            R = T.R
            k = int(np.round(np.arctan2(R[1, 0], R[0, 0]) / (np.pi / 2)))
            t = np.r_[np.round(T.translation[:2] / self.pitch) * self.pitch, 0.0]
            return Transform(Rotation.from_rotvec([0.0, 0.0, k * np.pi / 2]), t)
        return min(self.symmetries, key=lambda S: rotation_distance_deg(S.rotation, T.rotation)
                   + 100 * float(np.linalg.norm(S.translation - T.translation)))


def median_transform(cands: list[Transform], ref: Rotation) -> Transform:
    """Component-wise median of rotation vectors relative to ``ref`` and of translations."""
    d = np.median([(T.rotation * ref.inv()).as_rotvec() for T in cands], axis=0)
    t = np.median([T.translation for T in cands], axis=0)
    return Transform(Rotation.from_rotvec(d) * ref, t)


def _near(a: Transform, b: Transform, tol_deg: float, tol_m: float) -> bool:
    return rotation_distance_deg(a.rotation, b.rotation) <= tol_deg and \
        float(np.linalg.norm(a.translation - b.translation)) <= tol_m


def _consensus(cands: dict[int, list[Transform]], tol_deg: float, tol_m: dict[int, float]) -> Transform:
    """The candidate that the most shots have a candidate near (ties: the smaller sum of the
    shots' nearest rotation distances)."""
    best: tuple[int, float, Transform] | None = None
    for T in (T for ts in cands.values() for T in ts):
        n = sum(any(_near(u, T, tol_deg, tol_m[s]) for u in ts) for s, ts in cands.items())
        spread = -sum(min(rotation_distance_deg(u.rotation, T.rotation) for u in ts) for ts in cands.values())
        if best is None or (n, spread) > best[:2]:
            best = (n, spread, T)
    assert best is not None
    return best[2]


def _next_camera(placed: set[int], labelled: set[int], posed: dict[tuple[int, int], Transform], n_cam: int
                 ) -> tuple[int, list[int]]:
    """The unplaced camera sharing the most shots with the placed ones (``labelled``: the shots
    of their kept views), and those shots."""
    best: tuple[int, list[int]] = (-1, [])
    for c in range(n_cam):
        if c in placed:
            continue
        shots = sorted(s for cc, s in posed if cc == c and s in labelled)
        if len(shots) > len(best[1]):
            best = (c, shots)
    return best


def rig_start(posed: dict[tuple[int, int], Transform], names: list[str], moves: LabelMoves,
              tolerance_deg: float = 2.0, tolerance_rel: float = 0.01, relabel: bool = True) -> RigStart:
    """Connectivity check, labelling and extrinsics (module docstring). ``posed[(c, s)]`` is the
    target -> camera c pose of shot s by camera c's own calibration. ``relabel`` False takes every
    view as labelled and keeps every view (for comparison only: that is the pipeline that goes
    wrong on a symmetric target)."""
    check_connected(posed, names)
    n_cam = len(names)
    syms = moves.symmetries if relabel else [Transform.identity()]
    ident = Transform.identity()
    start = RigStart([ident] * n_cam, {k: ident for k in posed if k[0] == 0}, parent={0: -1})
    placed = {0}
    while len(placed) < n_cam:
        c, shots = _next_camera(placed, {s for _, s in start.labels}, posed, n_cam)
        if c < 0:
            rest = ", ".join(names[k] for k in range(n_cam) if k not in placed)
            raise RigConnectivityError(f"no kept view ties {rest} to the other cameras (their shared views were "
                                       "left out: " + "; ".join(start.dropped.values()) + ")")
        shot: dict[int, Transform] = {}
        from_cam: dict[int, int] = {}
        for s in shots:
            p = min(q for q in placed if (q, s) in start.labels)
            shot[s] = start.extrinsics[p].inverse() @ posed[(p, s)] @ start.labels[(p, s)]
            from_cam[s] = p
        cands = {s: [posed[(c, s)] @ T @ shot[s].inverse() for T in syms] for s in shots}
        tol_m = {s: max(0.003, tolerance_rel * float(np.linalg.norm(shot[s].translation))) for s in shots}
        ref = _consensus(cands, tolerance_deg, tol_m)
        kept = [min(ts, key=lambda u: rotation_distance_deg(u.rotation, ref.rotation)) for ts in cands.values()]
        kept = [u for u, s in zip(kept, shots, strict=True) if _near(u, ref, tolerance_deg, tol_m[s])]
        start.extrinsics[c] = median_transform(kept or [ref], ref.rotation)
        start.parent[c] = int(np.bincount([from_cam[s] for s in shots]).argmax())
        start.shared[c] = len(kept)
        for s in shots:
            raw = posed[(c, s)].inverse() @ start.extrinsics[c] @ shot[s]
            L = moves.nearest(raw) if relabel else ident
            if relabel and not _near(posed[(c, s)] @ L @ shot[s].inverse(), start.extrinsics[c], tolerance_deg,
                                     tol_m[s]):
                E = posed[(c, s)] @ L @ shot[s].inverse()
                start.dropped[(c, s)] = (
                    f"its pose disagrees with {names[from_cam[s]]}'s view of the same shot by "
                    f"{rotation_distance_deg(E.rotation, start.extrinsics[c].rotation):.2f} deg, "
                    f"{1000 * np.linalg.norm(E.translation - start.extrinsics[c].translation):.1f} mm against the "
                    "rig's other shots: the target moved between the exposures (cameras not synchronised?) or a "
                    "wrong detection")
                continue
            start.labels[(c, s)] = L
        for s in {s for cc, s in posed if cc == c} - set(shots):
            start.labels[(c, s)] = ident  # a shot no placed camera saw: its pose is its own
        placed.add(c)
    return start
