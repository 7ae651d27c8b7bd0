"""Grids of rings or discs: find every element, give it a row and a column, measure its edges.

1. Elliptical dark blobs (``find_blobs``): ring elements have a concentric hole of the expected
   radius ratio, disc elements none. Sizes must agree with their neighbours.
2. Lattice growth from a seed whose four nearest neighbours form a cross: each labelled element
   carries its two local lattice vectors, predicts its four neighbours, and takes the blob found
   within 30 % of a step. Local vectors follow perspective and strong distortion. An element
   reached twice with different labels means the lattice is ambiguous: the view is rejected.
3. Labels: the lattice of a regular grid is the same up to a translation and a rotation by a
   multiple of 90 degrees (180 for rows != cols) of the board; any labelling that maps the found
   elements onto the printed lattice without mirroring is therefore an exact correspondence (the
   board pose absorbs the difference). The labelling is chosen to fit inside rows x cols;
   partially visible boards keep the fully visible elements. Mirror images are not accepted.
4. Subpixel edges of every element (both edges of a ring) with :func:`refine_edge`; an element
   whose edge cannot be measured (clutter, occlusion) is dropped, never guessed.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..errors import PascalCalibError
from ..geometry import Ellipse, conics_from_ellipses, group_medians
from ..targets import CircleGrid, Target
from .detection import DetectionRefusal
from .edges import EdgeFit, refine_edges_batch


class GridError(PascalCalibError):
    """A grid not usable in this view; ``kind`` says why."""

    def __init__(self, message: str, kind: DetectionRefusal = DetectionRefusal.OTHER) -> None:
        super().__init__(message)
        self.kind = kind


def concentric_fit(outer: Ellipse, hole: Ellipse) -> tuple[float, float]:
    """How close an ellipse and its hole come to the image of two concentric circles of radii
    R > r, whatever the view: (spread, ratio). For such circles C_out^-1 C_in has the eigenvalues
    (1, 1, r^2 / R^2) up to scale in every view (a homography only conjugates it), while the
    offset of the two ellipses' centres grows with perspective (a close, tilted ring: 0.15-0.25
    of its size). ``spread``: relative difference of the two largest eigenvalues (0: concentric);
    ``ratio``: sqrt(smallest / their mean), r / R. Computed on the conics in the outer ellipse's
    frame, scaled to its size."""
    s = math.sqrt(outer.a * outer.b)
    o = _unit_conic(0.0, 0.0, outer.a / s, outer.b / s, outer.angle)
    h = _unit_conic((hole.cx - outer.cx) / s, (hole.cy - outer.cy) / s, hole.a / s, hole.b / s, hole.angle)
    try:
        with np.errstate(all="ignore"):
            w = np.sort(np.abs(np.linalg.eigvals(np.linalg.solve(o, h))))
    except np.linalg.LinAlgError:
        return math.inf, 0.0
    pair = (w[1] + w[2]) / 2
    if not np.all(np.isfinite(w)) or pair <= 0:
        return math.inf, 0.0
    return float((w[2] - w[1]) / pair), float(math.sqrt(w[0] / pair))


def _unit_conic(cx: float, cy: float, a: float, b: float, angle: float) -> np.ndarray:
    """The conic of an ellipse, scaled so that its value at the centre is -1."""
    c, s = math.cos(angle), math.sin(angle)
    ia, ib = 1 / (a * a), 1 / (b * b)
    p, q, r = c * c * ia + s * s * ib, c * s * (ia - ib), s * s * ia + c * c * ib
    u, v = -(p * cx + q * cy), -(q * cx + r * cy)
    return np.array([[p, q, u], [q, r, v], [u, v, -(u * cx + v * cy) - 1]])


def _element_candidates(blobs: list, grid: CircleGrid) -> list[tuple[Ellipse, Ellipse | None, bool]]:
    """(outer ellipse, inner ellipse or None, touches border) for each blob that can be an element."""
    out = []
    ratio = grid.inner_radius / grid.outer_radius if grid.kind == "ring" else 0.0
    for b in blobs:
        size = np.sqrt(b.ellipse.a * b.ellipse.b)
        hole = None
        for _, he in b.holes:
            r = np.sqrt(he.a * he.b) / size
            off = np.hypot(he.cx - b.ellipse.cx, he.cy - b.ellipse.cy) / size
            if grid.kind == "ring" and off < 0.2 and abs(r / ratio - 1) < 0.4:
                hole = he
        if grid.kind == "ring" and hole is None:
            continue
        if grid.kind == "disc" and any(np.sqrt(e.a * e.b) > 0.25 * size for _, e in b.holes):
            continue
        out.append((b.ellipse, hole, b.touches_border))
    return out


def label_lattice(centres: np.ndarray, sizes: np.ndarray) -> dict[int, tuple[int, int]]:
    """Integer lattice coordinates (i, j) for the candidates connected to the best seed."""
    n = len(centres)
    if n < 5:
        raise GridError(f"only {n} grid-like circle(s) found", DetectionRefusal.TOO_FEW_FEATURES)
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    np.fill_diagonal(d, np.inf)
    order = np.argsort(d, axis=1)[:, : min(8, n - 1)]

    def cross_quality(k: int) -> tuple[float, np.ndarray, np.ndarray] | None:
        """Two lattice steps at k: the shortest neighbour vector with an opposite partner, then the
        shortest non-parallel one with an opposite partner (foreshortening may make them differ
        by a factor of 3)."""
        vecs = centres[order[k]] - centres[k]
        lens = np.linalg.norm(vecs, axis=1)
        basis: list[np.ndarray] = []
        for a in np.argsort(lens):
            va = vecs[a]
            if basis and abs(basis[0][0] * va[1] - basis[0][1] * va[0]) < 0.5 * lens[a] * np.linalg.norm(basis[0]):
                continue  # parallel to the first step
            opp = np.linalg.norm(vecs + va, axis=1)
            b = int(np.argmin(opp))
            if opp[b] > 0.25 * lens[a]:
                continue
            basis.append((va - vecs[b]) / 2)
            if len(basis) == 2:
                break
        if len(basis) < 2:
            return None
        u, v = basis
        ratio = np.linalg.norm(u) / np.linalg.norm(v)
        if not 1 / 3 < ratio < 3:
            return None
        c = abs(u[0] * v[1] - u[1] * v[0]) / (np.linalg.norm(u) * np.linalg.norm(v))
        return c, u, v

    # the seed: the element nearest the centroid that has four grid neighbours
    centroid = centres.mean(0)
    found = None
    for k in np.argsort(np.hypot(*(centres - centroid).T)):
        q = cross_quality(int(k))
        if q is not None and q[0] > 0.5:
            found = (int(k), q[1], q[2])
            break
    if found is None:
        raise GridError("no element with four grid neighbours: not a grid, or too few circles visible",
                        DetectionRefusal.NO_TARGET)
    seed, u0, v0 = found
    return _grow_lattice(centres, sizes, seed, u0, v0)


def _grow_lattice(centres: np.ndarray, sizes: np.ndarray, seed: int, u0: np.ndarray, v0: np.ndarray
                  ) -> dict[int, tuple[int, int]]:
    """Lattice labels grown from ``seed`` (steps ``u0``, ``v0``): each labelled element predicts
    its four neighbours and takes the candidate found unambiguously near the prediction."""
    labels: dict[int, tuple[int, int]] = {seed: (0, 0)}
    # the growth in Python floats (numpy's per-call cost dominates 2-vectors), the nearest two
    # candidates of each prediction by one pass over all of them
    pts: list[list[float]] = centres.tolist()
    size: list[float] = sizes.tolist()
    cx, cy = np.ascontiguousarray(centres[:, 0]), np.ascontiguousarray(centres[:, 1])
    Vec = tuple[float, float]
    vectors: dict[int, tuple[Vec, Vec]] = {seed: ((float(u0[0]), float(u0[1])), (float(v0[0]), float(v0[1])))}
    taken: dict[tuple[int, int], int] = {(0, 0): seed}
    queue = deque([seed])
    while queue:
        k = queue.popleft()
        i, j = labels[k]
        u, v = vectors[k]
        xk, yk = pts[k]
        for (di, dj), (sx, sy) in (((1, 0), u), ((-1, 0), (-u[0], -u[1])), ((0, 1), v), ((0, -1), (-v[0], -v[1]))):
            back = taken.get((i - di, j - dj))
            if back is not None:  # continue the line through the previous elements: follows
                sx, sy = xk - pts[back][0], yk - pts[back][1]  # perspective and distortion
                back2 = taken.get((i - 2 * di, j - 2 * dj))
                if back2 is not None:  # spacing changes geometrically along a line under perspective
                    ratio = math.hypot(sx, sy) / max(math.hypot(pts[back][0] - pts[back2][0],
                                                                pts[back][1] - pts[back2][1]), 1e-9)
                    f = min(max(ratio, 0.7), 1.4)
                    sx, sy = sx * f, sy * f
            else:  # parallelogram rule from an adjacent, already labelled line
                for si, sj in ((dj, di), (-dj, -di)):
                    a_, b_ = taken.get((i + si, j + sj)), taken.get((i + si + di, j + sj + dj))
                    if a_ is not None and b_ is not None:
                        sx, sy = pts[b_][0] - pts[a_][0], pts[b_][1] - pts[a_][1]
                        break
            d2 = (cx - (xk + sx)) ** 2 + (cy - (yk + sy)) ** 2
            m = int(d2.argmin())
            dm = float(d2[m])
            d2[m] = np.inf
            dm2 = float(d2.min()) if len(d2) > 1 else np.inf
            # an unambiguous match only: close to the prediction, the runner-up far from it
            step_len = math.hypot(sx, sy)
            if dm > (0.3 * step_len) ** 2 or dm2 < (0.6 * step_len) ** 2 or not (0.6 < size[m] / size[k] < 1.6):
                continue
            lab = (i + di, j + dj)
            if m in labels:
                if labels[m] != lab:
                    raise GridError(f"inconsistent grid labelling: element at ({pts[m][0]:.0f}, "
                                    f"{pts[m][1]:.0f}) reached as {labels[m]} and {lab}", DetectionRefusal.AMBIGUOUS)
                continue
            if lab in taken:
                continue
            labels[m] = lab
            taken[lab] = m
            ax, ay = pts[m][0] - xk, pts[m][1] - yk
            vectors[m] = ((ax * di, ay * di), v) if di else (u, (ax * dj, ay * dj))
            queue.append(m)
    return labels


def _complete_elements(target: Target, grid: CircleGrid, idx_of: list[int], fits: list[EdgeFit | None]
                       ) -> list[tuple[int, np.ndarray, np.ndarray, float, float]]:
    """(circle index, points, conic, median blur, rms) of every measured edge of the elements
    whose edges were all measured (a ring counts with both)."""
    measured = {i for i, f in zip(idx_of, fits, strict=True) if f is not None}
    kept: list[tuple[int, EdgeFit]] = []
    for i, f in zip(idx_of, fits, strict=True):
        outer_idx = i if target.circles[i].dark_inside else i - 1
        if f is None or outer_idx not in measured or (grid.kind == "ring" and outer_idx + 1 not in measured):
            continue
        kept.append((i, f))
    if not kept:
        return []
    owner = np.repeat(np.arange(len(kept)), [len(f.width) for _, f in kept])  # each edge's median blur, at once
    widths = group_medians(np.concatenate([f.width for _, f in kept]), owner, len(kept)).tolist()
    return [(i, f.points, f.conic, wd, f.rms) for (i, f), wd in zip(kept, widths, strict=True)]


def detect_grid(work: np.ndarray, blobs: list, target: Target, grid_index: int, *,
                max_blur: float, spacing: float, curvature_correction: bool
                ) -> tuple[list[tuple[int, np.ndarray, np.ndarray, float, float]], str]:
    """Edges of the grid's elements: (circle index, points, conic, width, rms) for every measured
    edge, and a note on what was dropped. Raises :class:`GridError` when the grid is not usable."""
    grid = target.grids[grid_index]
    cands = _element_candidates(blobs, grid)
    if len(cands) < 5:
        raise GridError(f"no {grid.kind} grid found ({len(cands)} {grid.kind}-like circle(s))",
                        DetectionRefusal.NO_TARGET)
    centres = np.array([[e.cx, e.cy] for e, _, _ in cands])
    sizes = np.array([np.sqrt(e.a * e.b) for e, _, _ in cands])
    keys, rows_idx, cols_idx = _grid_rows_cols(centres, sizes, grid)
    req = _edge_requests(cands, keys, rows_idx, cols_idx, target=target, grid_index=grid_index)
    conics = list(conics_from_ellipses(np.array(req.ellipses, float)))
    # one pass: the threshold contours' ellipses are close enough for the profiles' windows and
    # normals (a second, re-centred pass measured no better in `pascal-calib study grids`); one
    # profile per 3 px of arc (default spacing): the refinement keeps ~10 points per element of a
    # 70-element view, and denser profiles measured no better there either. Outer edges: profiles
    # that see another edge just beyond their window (the sheet's border next to the outer
    # elements, a close neighbour under strong tilt) are not used (refine_edges_batch,
    # look_outside). A ring's two edges are fitted as one band (partners): a single step fitted to
    # a 3-6 px band is pulled by the other edge's blurred tail (README, Trust: ring grids).
    fits = refine_edges_batch(work, conics, np.array(req.windows), spacing=2 * spacing, max_width=max_blur,
                              curvature_correction=curvature_correction, look_outside=np.array(req.look_outside),
                              partners=np.array(req.partners, int))
    edges = _complete_elements(target, grid, req.idx_of, fits)
    dropped = req.dropped + len({i if target.circles[i].dark_inside else i - 1 for i in req.idx_of}) - len(
        {e[0] for e in edges if target.circles[e[0]].dark_inside})
    note = f"{dropped} element(s) dropped (at the border or edge not measurable)" if dropped else ""
    return edges, note


def _grid_rows_cols(centres: np.ndarray, sizes: np.ndarray, grid: CircleGrid
                    ) -> tuple[list[int], np.ndarray, np.ndarray]:
    """Label the candidates' centres (n, 2) by their lattice (:func:`label_lattice`) and map the
    labels to the grid's rows and columns: (candidate indices, row, column of each). The lattice
    basis is chosen to make the labelled set most compact (a diagonal step would shear it), and
    +column, +row keep the target's handedness (a labelling is never mirrored)."""
    labels = label_lattice(centres, sizes)
    if len(labels) < 6:
        raise GridError(f"only {len(labels)} connected grid element(s) found", DetectionRefusal.TOO_FEW_FEATURES)
    ij = np.array(list(labels.values()))
    keys = list(labels.keys())
    best = None
    for T in (np.eye(2, dtype=int), *(np.array(m) for m in ([[1, 1], [0, 1]], [[1, -1], [0, 1]],
                                                             [[1, 0], [1, 1]], [[1, 0], [-1, 1]]))):
        t_ij = ij @ T.T
        area = (np.ptp(t_ij[:, 0]) + 1) * (np.ptp(t_ij[:, 1]) + 1)
        if best is None or area < best[0]:
            best = (area, t_ij)
    assert best is not None
    ij = best[1]
    # orientation: +i and +j image directions must not be mirrored with respect to the target's x, y
    ci = {(int(a), int(b)): centres[k] for k, (a, b) in zip(keys, ij, strict=True)}
    du = [ci[(a + 1, b)] - ci[(a, b)] for (a, b) in ci if (a + 1, b) in ci]
    dv = [ci[(a, b + 1)] - ci[(a, b)] for (a, b) in ci if (a, b + 1) in ci]
    if not du or not dv:
        raise GridError("grid elements found along one line only", DetectionRefusal.TOO_FEW_FEATURES)
    mu, mv = np.mean(du, 0), np.mean(dv, 0)
    if (mu[0] * mv[1] - mu[1] * mv[0]) < 0:  # i -> col (x), j -> row (y) must keep handedness
        ij[:, 1] = -ij[:, 1]
    span_i, span_j = int(np.ptp(ij[:, 0])) + 1, int(np.ptp(ij[:, 1])) + 1
    if span_i <= grid.cols and span_j <= grid.rows:
        return keys, ij[:, 1] - ij[:, 1].min(), ij[:, 0] - ij[:, 0].min()
    if span_j <= grid.cols and span_i <= grid.rows:
        # rotate the labelling by 90 degrees (i, j) -> (j, -i): still not mirrored
        return keys, (-ij[:, 0]) - (-ij[:, 0]).min(), ij[:, 1] - ij[:, 1].min()
    raise GridError(f"found a {span_i} x {span_j} lattice, larger than the {grid.cols} x {grid.rows} grid "
                    "(another grid or clutter in view?)", DetectionRefusal.AMBIGUOUS)


@dataclass
class _EdgeRequests:
    """The edges to measure in one batch: start ellipses (cx, cy, a, b, angle), profile half-windows,
    target circle indices, whether to look beyond the edge, the partner edge of a ring's band (-1:
    none), and how many elements were dropped for touching the image border."""

    ellipses: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    windows: list[float] = field(default_factory=list)
    idx_of: list[int] = field(default_factory=list)
    look_outside: list[bool] = field(default_factory=list)
    partners: list[int] = field(default_factory=list)
    dropped: int = 0


def _edge_requests(cands: list, keys: list[int], rows_idx: np.ndarray, cols_idx: np.ndarray, *,
                   target: Target, grid_index: int) -> _EdgeRequests:
    """One batched measurement for all edges of the labelled elements; the profile window (0.45 of
    the band, 1.5-25 px) must not reach the next edge."""
    grid = target.grids[grid_index]
    req = _EdgeRequests()
    for k, r, c in zip(keys, rows_idx, cols_idx, strict=True):
        outer, inner, touches = cands[k]
        if touches:
            req.dropped += 1
            continue
        idx = target.grid_circle_index(grid_index, int(r), int(c))
        so = math.sqrt(outer.a * outer.b)
        band = so - math.sqrt(inner.a * inner.b) if inner is not None else so
        hw = min(max(0.45 * band, 1.5), 25.0)
        req.ellipses.append((outer.cx, outer.cy, outer.a, outer.b, outer.angle))
        req.windows.append(hw)
        req.idx_of.append(idx)
        req.look_outside.append(True)  # the outer edge: a disc's, or a ring's (the sheet's border beyond)
        req.partners.append(-1)
        if grid.kind == "ring" and inner is not None:
            req.ellipses.append((inner.cx, inner.cy, inner.a, inner.b, inner.angle))
            req.windows.append(hw)
            req.idx_of.append(idx + 1)
            req.look_outside.append(False)
            req.partners[-1] = len(req.ellipses) - 1  # the ring's two edges bound one dark band: fitted together
            req.partners.append(len(req.ellipses) - 2)
    return req
