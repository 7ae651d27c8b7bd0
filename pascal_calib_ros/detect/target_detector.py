"""Detect any shipped target in a grey image (:func:`detect_target`): rings, discs, grids of
them and checkerboards; the circles' edges are measured to subpixel accuracy.

1. Dark blobs by global (Otsu) and, failing that, local thresholding of a downscaled copy;
   contours with their holes (``cv2.findContours``, two-level hierarchy).
2. Candidates: blobs whose outline is an ellipse (fit residual small against the size); a ring is
   such a blob with one elliptical, nearly concentric hole of the expected radius ratio; a disc
   has no hole. Features are paired with the target by their sizes and layout.
3. Every circle edge is refined by :func:`refine_edge`. A feature touching the image border, too
   blurred or absent rejects the view with a reason: a detection never guesses.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.conic import (
    Ellipse,
    ellipses_from_conics,
    fit_conics_algebraic,
    group_medians,
    sampson_distances,
)
from ..targets import Target
from .detection import DEFAULT_PARAMS, CircleEdge, Detection, DetectionParams
from .edges import EdgeError, EdgeFit, refine_edge


@dataclass
class _Blob:
    contour: np.ndarray  # full-resolution coordinates (N, 2)
    ellipse: Ellipse
    holes: list[tuple[np.ndarray, Ellipse]]
    touches_border: bool
    fit_residual: float


def _to_float(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype == np.uint8:
        return image.astype(np.float32)
    if image.dtype == np.uint16:
        return image.astype(np.float32) / 257.0
    return image.astype(np.float32)


def _grey_range(image: np.ndarray, gray: np.ndarray) -> float:
    """Highest minus lowest grey level of ``gray`` (``_to_float(image)``), by one
    ``cv2.minMaxLoc`` pass over the smallest array holding them: a grey uint8 or uint16 image
    itself (5 MP: 0.05 ms instead of numpy's two passes over the floats, 0.8 ms)."""
    src = image if image.ndim == 2 and image.dtype in (np.uint8, np.uint16) else gray
    lo, hi, _, _ = cv2.minMaxLoc(src)
    return float(hi - lo) / (257.0 if src.dtype == np.uint16 else 1.0)


def find_blobs(gray: np.ndarray, params: DetectionParams, modes: tuple[str, ...] = ("otsu", "adaptive")
               ) -> tuple[list[_Blob], int]:
    """Elliptical dark blobs (with their elliptical holes), full-resolution coordinates, and the
    number of large non-elliptical dark shapes cut by the image border. Thresholds in ``modes``
    are tried in turn until one gives a blob with a hole (a ring); the last one's blobs are kept."""
    h, w = gray.shape
    scale = 1
    small = gray
    while small.shape[0] * small.shape[1] > params.working_pixels:
        small = cv2.pyrDown(small)
        scale *= 2
    small8 = np.clip(small, 0, 255).astype(np.uint8)
    blobs: list[_Blob] = []
    cut = 0
    for mode in modes:
        if mode == "otsu":
            _, mask = cv2.threshold(small8, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
        else:
            block = max(3, (max(small8.shape) // 8) | 1)
            mask = cv2.adaptiveThreshold(small8, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, 10)
        blobs, cut = _blobs_from_mask(mask, scale, w, h, params, small)
        if any(b.holes for b in blobs) or mode == modes[-1]:
            break
    return blobs, cut


def _sobel_magnitude_at(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """|3x3 Sobel gradient| / 8 (grey levels per pixel) of ``img`` at integer pixels (x, y)."""
    h, w = img.shape
    x0, x1, x2 = np.maximum(x - 1, 0), x, np.minimum(x + 1, w - 1)
    y0, y1, y2 = np.maximum(y - 1, 0), y, np.minimum(y + 1, h - 1)
    gx = (img[y0, x2] - img[y0, x0]) + 2 * (img[y1, x2] - img[y1, x0]) + (img[y2, x2] - img[y2, x0])
    gy = (img[y2, x0] - img[y0, x0]) + 2 * (img[y2, x1] - img[y0, x1]) + (img[y2, x2] - img[y0, x2])
    return np.hypot(gx.astype(float), gy.astype(float)) / 8.0


def _blobs_from_mask(mask: np.ndarray, scale: int, w: int, h: int, params: DetectionParams,
                     img: np.ndarray) -> tuple[list[_Blob], int]:
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hier is None:
        return [], 0
    hier = hier[0]
    min_r = params.min_radius / scale
    margin = params.border_margin
    sh, sw = mask.shape
    # cheap tests first, then one batched edge-strength median and one batched ellipse fit
    cand: list[tuple[int, bool]] = []
    lengths = np.fromiter(map(len, contours), int, len(contours))
    for i in np.flatnonzero((hier[:, 3] == -1) & (lengths >= 12)).tolist():  # holes: through their parent
        x, y, bw, bh = cv2.boundingRect(contours[i])
        if min(bw, bh) < 2 * min_r:
            continue
        cand.append((i, x <= 1 or y <= 1 or x + bw >= sw - 1 or y + bh >= sh - 1))
    if not cand:
        return [], 0
    cpts = [contours[i][::2, 0, :] for i, _ in cand]  # every other pixel is plenty for a median
    owner = np.repeat(np.arange(len(cand)), [len(c) for c in cpts])
    allp = np.concatenate(cpts)
    strength = group_medians(_sobel_magnitude_at(img, allp[:, 0], allp[:, 1]), owner, len(cand))
    strong = [k for k in range(len(cand)) if strength[k] >= params.min_edge_strength]  # else soft shading
    holes_of = {}
    for k in strong:
        hs, j = [], hier[cand[k][0]][2]
        while j != -1:
            if len(contours[j]) >= 12:
                hs.append(j)
            j = hier[j][0]
        holes_of[k] = hs
    to_fit = [cand[k][0] for k in strong] + [j for k in strong for j in holes_of[k]]
    # full-resolution coordinates of every contour to fit, converted in one pass
    pts_of: dict[int, np.ndarray] = {}
    if to_fit:
        full = np.concatenate([contours[i][:, 0, :] for i in to_fit]).astype(float) * scale + (scale - 1) / 2
        pts_of = dict(zip(to_fit, np.split(full, np.cumsum([len(contours[i]) for i in to_fit])[:-1]), strict=True))
    fits = dict(zip(to_fit, _ellipses_of([pts_of[i] for i in to_fit]), strict=True))
    out: list[_Blob] = []
    cut = 0
    for k in strong:
        i, at_border = cand[k]
        pts = pts_of[i]
        fit = fits[i]
        x, y, bw, bh = cv2.boundingRect(contours[i])
        if fit is None or fit[1] > params.ellipse_tolerance * min(fit[0].a, fit[0].b) + 0.7 * scale:
            if at_border and bw * bh < 0.5 * sw * sh:
                cut += 1
            continue
        e, res = fit
        # the contour's extent at full resolution, from its bounding box (the same integers)
        x0, y0 = x * scale + (scale - 1) / 2, y * scale + (scale - 1) / 2
        x1, y1 = (x + bw - 1) * scale + (scale - 1) / 2, (y + bh - 1) * scale + (scale - 1) / 2
        touches = (x0 < margin + scale or y0 < margin + scale
                   or x1 > w - 1 - margin - scale or y1 > h - 1 - margin - scale)
        holes = []
        for j in holes_of[k]:
            hf = fits[j]
            if hf is not None and hf[1] < params.ellipse_tolerance * min(hf[0].a, hf[0].b) + 0.7 * scale:
                holes.append((pts_of[j], hf[0]))
        out.append(_Blob(pts, e, holes, touches, res))
    return out, cut


def _ellipses_of(contours: list[np.ndarray]) -> list[tuple[Ellipse, float] | None]:
    """Ellipses of many contours by one batched algebraic fit: the fitted ellipse and the median
    |Sampson distance| of its contour (None where no ellipse fits or the contour is too short)."""
    if not contours:
        return []
    n = len(contours)
    owner = np.repeat(np.arange(n), [len(c) for c in contours])
    pts = np.concatenate(contours)
    C, ok = fit_conics_algebraic(pts, owner, n)
    par, real = ellipses_from_conics(np.where(ok[:, None, None], C, np.eye(3)))
    ok &= real & np.isfinite(par).all(1) & (par[:, 2] > 0) & (par[:, 3] > 0)
    ok &= np.array([len(c) >= 8 for c in contours])
    res = group_medians(np.abs(sampson_distances(C, pts, owner)), owner, n)
    return [(Ellipse(*(float(v) for v in par[k])), float(res[k])) if ok[k] else None for k in range(n)]


def _edge(gray: np.ndarray, ellipse: Ellipse, params: DetectionParams) -> EdgeFit:
    return refine_edge(gray, ellipse.to_conic(), spacing=params.edge_spacing, max_width=params.max_blur,
                       curvature_correction=params.curvature_correction)


def detect_target(image: np.ndarray, target: Target, params: DetectionParams = DEFAULT_PARAMS,
                  name: str = "", checkerboard: bool = True) -> Detection:
    """Detect ``target`` in a grey (or BGR) image. Never raises for image content: a view that
    cannot be used comes back with ``reason`` set."""
    gray = _to_float(image)
    h, w = gray.shape
    det = Detection(w, h, name=name)
    if gray.size == 0 or (image.dtype.kind == "f" and not np.isfinite(gray).all()):  # integers are finite
        det.reason = "empty or invalid image"
        return det
    if min(h, w) < 16:
        det.reason = f"image too small ({w}x{h})"
        return det
    if _grey_range(image, gray) < 20:
        det.reason = "no contrast in the image (lens cap, exposure?)"
        return det
    work = gray
    if params.gamma != 1.0:
        work = (255.0 * (np.clip(gray, 0, 255) / 255.0) ** params.gamma).astype(np.float32)
    if target.grids:
        return _detect_grids(gray, work, target, params, det)
    # blobs are rings and discs; a checkerboard alone does not need them (half its time at 800x600)
    blobs, cut_shapes = find_blobs(gray, params) if target.rings or target.discs else ([], 0)
    if target.rings:
        try:
            ring_blob, hole = _pick_ring(blobs, target, params, cut_shapes)
        except _Reject as r:
            det.reason = str(r)
            return det
        try:
            outer = _edge(work, ring_blob.ellipse, params)
            inner = _edge(work, hole, params)
        except EdgeError as exc:
            det.reason = f"ring: {exc}"
            return det
        det.edges.append(CircleEdge(0, outer.points, outer.conic, float(np.median(outer.width)), outer.rms))
        det.edges.append(CircleEdge(1, inner.points, inner.conic, float(np.median(inner.width)), inner.rms))
        if target.discs:
            disc_idx = 2 * len(target.rings)
            try:
                disc_blob = _pick_disc(blobs, ring_blob, target, params)
                fit = _edge(work, disc_blob.ellipse, params)
                det.edges.append(CircleEdge(disc_idx, fit.points, fit.conic, float(np.median(fit.width)), fit.rms))
            except (_Reject, EdgeError) as exc:
                det.reason = f"disc: {exc}"
                return det
    elif target.discs:
        det.reason = "targets without a ring are not supported by the detector yet"
        return det
    if checkerboard and target.checkerboards:
        from .checkerboard import find_checkerboard

        grey8 = image if image.ndim == 2 and image.dtype == np.uint8 else np.clip(gray, 0, 255).astype(np.uint8)
        corners = find_checkerboard(grey8, target, det)
        if corners is None and not target.rings:
            det.reason = det.reason or "checkerboard not found"
            return det
        det.corners = corners
    return det


class _Reject(Exception):
    pass


def _detect_grids(gray: np.ndarray, work: np.ndarray, target: Target, params: DetectionParams,
                  det: Detection) -> Detection:
    from dataclasses import replace

    from .grids import GridError, detect_grid

    # a disc grid has no holes: the Otsu pass could only be discarded, go straight to the adaptive one
    modes = ("adaptive",) if all(g.kind == "disc" for g in target.grids) else ("otsu", "adaptive")
    blobs, _ = find_blobs(gray, replace(params, min_radius=min(params.min_radius, 4.0)), modes)
    notes = []
    for gi in range(len(target.grids)):
        try:
            edges, note = detect_grid(work, blobs, target, gi, max_blur=params.max_blur, spacing=params.edge_spacing,
                                      curvature_correction=params.curvature_correction)
        except GridError as e:
            det.reason = str(e)
            return det
        det.edges += [CircleEdge(i, p, c, w, r) for i, p, c, w, r in edges]
        if note:
            notes.append(note)
    n_elem = len({e.circle for e in det.edges if target.circles[e.circle].dark_inside})
    if n_elem < 6:
        det.reason = f"only {n_elem} grid element(s) measured; need 6"
    det.note = "; ".join(notes)
    return det


def _pick_ring(blobs: list[_Blob], target: Target, params: DetectionParams, cut_shapes: int = 0
               ) -> tuple[_Blob, Ellipse]:
    ring = target.rings[0]
    ratio = ring.inner_radius / ring.outer_radius
    cands: list[tuple[float, _Blob, Ellipse]] = []
    cut = False
    for b in blobs:
        if min(b.ellipse.a, b.ellipse.b) < params.min_radius:
            continue
        for _, he in b.holes:
            size = np.sqrt(b.ellipse.a * b.ellipse.b)
            off = np.hypot(he.cx - b.ellipse.cx, he.cy - b.ellipse.cy) / size
            r = np.sqrt(he.a * he.b) / size
            if off < 5 * params.ellipse_tolerance and abs(r / ratio - 1) < 0.35 + 5 * params.ellipse_tolerance:
                if b.touches_border:
                    cut = True
                    continue
                cands.append((size, b, he))
    if not cands:
        if cut:
            raise _Reject("ring cut by the image border (keep the whole ring in view)")
        if cut_shapes:
            raise _Reject("no complete ring found; a dark shape is cut by the image border "
                          "(target partly out of view?)")
        raise _Reject("no ring found")
    if len(cands) > 1:
        cands.sort(key=lambda c: -c[0])
        if cands[1][0] > 0.7 * cands[0][0]:
            raise _Reject(f"{len(cands)} ring-like shapes of similar size in view: ambiguous")
    return cands[0][1], cands[0][2]


def _pick_disc(blobs: list[_Blob], ring_blob: _Blob, target: Target, params: DetectionParams) -> _Blob:
    ring, disc = target.rings[0], target.discs[0]
    size_ratio = disc.radius / ring.outer_radius
    dist_ratio = np.hypot(disc.center[0] - ring.center[0], disc.center[1] - ring.center[1]) / ring.outer_radius
    rs = np.sqrt(ring_blob.ellipse.a * ring_blob.ellipse.b)
    best: tuple[float, _Blob] | None = None
    cut = False
    for b in blobs:
        size = np.sqrt(b.ellipse.a * b.ellipse.b)
        if b is ring_blob or any(np.sqrt(e.a * e.b) > 0.2 * size for _, e in b.holes):
            continue
        if size < params.min_radius or b.fit_residual > 2 / 3 * params.ellipse_tolerance * size + 0.7:
            continue
        sr = size / rs
        dr = np.hypot(b.ellipse.cx - ring_blob.ellipse.cx, b.ellipse.cy - ring_blob.ellipse.cy) / rs
        score = abs(np.log(sr / size_ratio)) + abs(np.log(dr / dist_ratio))
        if abs(np.log(sr / size_ratio)) > 0.6 or abs(np.log(dr / dist_ratio)) > 0.6:
            continue
        if b.touches_border:
            cut = True
            continue
        if best is None or score < best[0]:
            best = (score, b)
    if best is None:
        raise _Reject("disc cut by the image border" if cut else "no disc found beside the ring")
    return best[1]
