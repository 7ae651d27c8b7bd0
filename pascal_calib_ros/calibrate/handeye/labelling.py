"""Symmetric targets labelled consistently through the robot chain: a grid that looks the same turned
by 180 degrees may be labelled turned in some views; each view's labelling is chosen among the
target's symmetries so that the motion pairs (A, B) agree in their screw invariants (rotation angle
and the translation along the axis, which AX = XB preserves whatever X is), then again against the
chain with X and Y from the closed form."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry import Transform
from ...modes import HandEyeMode
from ...targets import Target
from ..solver.observations import ViewData
from .closed_form import chain_disagreement, hand_eye_closed_form


def _square_colour(board: object, xy: np.ndarray) -> np.ndarray:
    x0, y0 = board.origin  # type: ignore[attr-defined]
    s = board.square_size  # type: ignore[attr-defined]
    i = np.floor((xy[:, 0] - x0) / s).astype(int)
    j = np.floor((xy[:, 1] - y0) / s).astype(int)
    return (i + j) % 2


def target_symmetries(target: Target, origin: tuple[float, float]) -> list[Transform]:
    """The rotations of the sheet (by 90, 180, 270 degrees about the features' centre) that map
    every circle (centre, radius, dark side) and every checkerboard corner and square colour onto
    the target again, as transforms of the refinement's local frame; identity first."""
    if len(target.checkerboards) < len(target.boards):
        return [Transform.identity()]  # a marker board's ids fix the labelling
    pts = [np.array([c.center for c in target.circles]).reshape(-1, 2)]
    for b in target.checkerboards:
        pts.append(b.corner_points())
    allp = np.concatenate(pts)
    if len(allp) == 0:
        return [Transform.identity()]
    ctr = (allp.min(0) + allp.max(0)) / 2
    out = [Transform.identity()]
    circ = np.array([[c.center[0], c.center[1], c.radius, float(c.dark_inside)] for c in target.circles]).reshape(-1, 4)
    for k in (1, 2, 3):
        th = k * np.pi / 2
        Rz = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])

        def rot(p: np.ndarray, Rz: np.ndarray = Rz) -> np.ndarray:
            return (p - ctr) @ Rz.T + ctr

        ok = True
        if len(circ):
            moved = np.c_[rot(circ[:, :2]), circ[:, 2:]]
            d = np.abs(moved[:, None, :] - circ[None, :, :]).max(2)
            ok = bool(np.all(d.min(1) < 1e-7))
        for b in target.checkerboards:
            cp = b.corner_points()
            mc = rot(cp)
            ok = ok and bool(np.all(np.abs(mc[:, None, :] - cp[None, :, :]).max(2).min(1) < 1e-7))
            # the colour of the squares must map too (sample square centres)
            x0, y0, x1, y1 = b.extent
            s = b.square_size
            g = np.stack(np.meshgrid(np.arange(x0 + s / 2, x1, s), np.arange(y0 + s / 2, y1, s)), -1).reshape(-1, 2)
            ok = ok and bool(np.all(_square_colour(b, g) == _square_colour(b, rot(g))))
        if ok:
            # as a local-frame transform: x_local = x - origin
            o = np.asarray(origin, float)
            R3 = np.eye(3)
            R3[:2, :2] = Rz
            t = np.r_[(ctr - o) - Rz @ (ctr - o), 0.0]
            out.append(Transform.from_rt(R3, t))
    return out


def relabelled(view: ViewData, T: Transform) -> ViewData:
    """The view's observations under the labelling turned by the symmetry T (centres -> T^-1)."""
    Ti = T.inverse()

    def tf(p: np.ndarray) -> np.ndarray:
        if len(p) == 0:
            return p
        return Ti.apply(np.c_[p, np.zeros(len(p))])[:, :2]

    return replace(view, centers=tf(view.centers), corner_obj=tf(view.corner_obj))


def _screw(T: Transform) -> tuple[float, float]:
    """Rotation angle and translation along the axis: invariants of A X = X B."""
    rv = T.rotvec
    ang = float(np.linalg.norm(rv))
    pitch = float(T.translation @ rv / ang) if ang > 1e-9 else float(np.linalg.norm(T.translation))
    return ang, pitch


def _choose_labels(M: list[Transform], C: list[Transform], syms: list[Transform], ref: int) -> list[int]:
    """Per view the symmetry whose motion from/to view ``ref`` has the screw invariants of the
    robot's motion."""
    out = []
    for i in range(len(M)):
        if i == ref:
            out.append(0)
            continue
        a_ang, a_pitch = _screw(M[ref].inverse() @ M[i])
        best, arg = np.inf, 0
        for s, T in enumerate(syms):
            b_ang, b_pitch = _screw(C[ref] @ (C[i] @ T).inverse())
            score = abs(a_ang - b_ang) + abs(abs(a_pitch) - abs(b_pitch)) / 0.1
            if score < best:
                best, arg = score, s
        out.append(arg)
    return out


def label_consistently(M: list[Transform], C: list[Transform], views: list[ViewData], syms: list[Transform],
                       mode: HandEyeMode, target_name: str) -> tuple[list[Transform], list[ViewData], list[str]]:
    """Every view's labelling among the target's symmetries ``syms`` chosen consistently with the
    robot chain (module docstring): the labelling that best fits, over three reference views, then
    each view again against X and Y of the closed form; the session's labelling is kept where most
    views were detected. Returns the camera poses and observations relabelled, and the warnings."""
    best: tuple[float, list[int]] | None = None
    for ref in range(min(3, len(M))):
        lab = _choose_labels(M, C, syms, ref)
        Cl = [c @ syms[s] for c, s in zip(C, lab, strict=True)]
        X, Y = hand_eye_closed_form(M, Cl)
        mm, deg = chain_disagreement(M, X, Y, Cl, mode)
        score = float(np.median(mm) + 10 * np.median(deg))
        if best is None or score < best[0]:
            best = (score, lab)
    assert best is not None
    turns = [syms[s] for s in best[1]]
    Cl = [c @ T for c, T in zip(C, turns, strict=True)]
    X, Y = hand_eye_closed_form(M, Cl)
    errs = []  # again against the chain with X and Y of the closed form: per symmetry, every view at once
    for T in syms:
        mm, deg = chain_disagreement(M, X, Y, [c @ T for c in Cl], mode)
        errs.append(mm + 10 * deg)
    best = np.argmin(np.array(errs), 0)
    turns = [t @ syms[int(b)] for t, b in zip(turns, best, strict=True)]
    # the labelling of the whole session is free up to the symmetry (X is not affected; Y is turned): keep
    # the one most views were detected in
    g = min(syms, key=lambda G: sum((T @ G).angle_deg() > 1.0 for T in turns))
    turns = [T @ g for T in turns]
    turned_by = ", ".join(f"{T.angle_deg():.0f}" for T in syms[1:])
    warnings = [f"target {target_name!r} looks the same turned by {turned_by} deg: its pose is reported in the "
                "labelling most views were detected in"]
    C, views = list(C), list(views)
    n_turned = 0
    for i, T in enumerate(turns):
        if T.angle_deg() > 1.0:
            n_turned += 1
            C[i] = C[i] @ T
            views[i] = relabelled(views[i], T)
    if n_turned:
        warnings.append(f"{n_turned} view(s) were labelled turned by a symmetry of the target; relabelled "
                        "consistently with the robot chain")
    return C, views, warnings
