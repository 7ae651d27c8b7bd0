"""Detect any shipped target in a grey image (:func:`detect_target`): rings, discs, grids of
them and checkerboards; the circles' edges are measured to subpixel accuracy.

1. Dark blobs by global (Otsu) and, failing that, local thresholding of a downscaled copy;
   contours with their holes (``cv2.findContours``, two-level hierarchy).
2. Candidates: blobs whose outline is an ellipse (fit residual small against the size); a ring is
   such a blob with an elliptical hole that, with it, is the image of two concentric circles of
   the expected radius ratio (:func:`.grids.concentric_fit`, a projective test: a close, tilted
   ring's two ellipses are far from concentric); a disc has no hole. Features are paired with the
   target by their sizes and layout.
3. Every circle edge is refined by :func:`refine_edge`. A feature cut by the image border (an
   elliptical arc leaving the frame; not the sheet around it), too small, too blurred or absent
   rejects the view with a reason that says which: a detection never guesses.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from ..geometry import (
    CircularPointError,
    Ellipse,
    centre_image_from_ring,
    group_medians,
)
from ..targets import Target
from .blob_tools import ellipses_of, grey_range, room_to_border, sobel_magnitude_at, to_float
from .contour_edges import keep_on_traced, refine_along_contour
from .detection import DEFAULT_PARAMS, CircleEdge, Detection, DetectionParams, DetectionRefusal
from .edges import EdgeError, EdgeFit, refine_edge
from .grids import concentric_fit


@dataclass
class _Blob:
    contour: np.ndarray  # full-resolution coordinates (N, 2)
    ellipse: Ellipse
    holes: list[tuple[np.ndarray, Ellipse]]
    touches_border: bool
    fit_residual: float
    scale: int = 1  # the downscaling of the image the contours were traced in
    # False: a shape with a hole, whole in the image, whose outline is no ellipse (kept so that a
    # refused ring-like shape is named, not lost: :func:`_pick_ring`); no other feature uses it
    outline_ok: bool = True
    # the ellipses of its holes that are no ellipse's image (bent: fit residual over the limit) of a
    # shape whose outline is no ellipse either (a close ring through a wide lens): named, not lost
    bent_holes: list[tuple[np.ndarray, Ellipse]] = field(default_factory=list)


@dataclass
class _Cut:
    """A dark, non-elliptical shape with strong edges cut by the image border: its outline
    (N, 2), traced in an image of ``size`` (width, height) downscaled by ``scale``. Whether it is
    a circle's image leaving the frame is decided when a rejection needs it (:func:`_cut_circle`)."""

    contour: np.ndarray
    size: tuple[int, int]
    scale: int
    image: np.ndarray | None = None  # set: the edge strength off the border is still to be checked


def find_blobs(gray: np.ndarray, params: DetectionParams, modes: tuple[str, ...] = ("otsu", "adaptive")
               ) -> tuple[list[_Blob], list[_Cut]]:
    """Elliptical dark blobs (with their elliptical holes), full-resolution coordinates, and the
    non-elliptical dark shapes cut by the image border (of every pass). A shape whole in the image
    with an elliptical hole but an outline that is no ellipse is kept too, marked ``outline_ok``
    False, for the ring's refusal to name it. Thresholds in ``modes`` are tried in turn until one
    gives a blob with a hole (a ring); the last one's blobs are kept."""
    h, w = gray.shape
    scale = 1
    small = gray
    while small.shape[0] * small.shape[1] > params.working_pixels:
        small = cv2.pyrDown(small)
        scale *= 2
    small8 = np.clip(small, 0, 255).astype(np.uint8)
    blobs: list[_Blob] = []
    cut: list[_Cut] = []
    for mode in modes:
        if mode == "otsu":
            _, mask = cv2.threshold(small8, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
        else:
            block = max(3, (max(small8.shape) // 8) | 1)
            mask = cv2.adaptiveThreshold(small8, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, 10)
        blobs, cut_here = _blobs_from_mask(mask, scale, w, h, params, small)
        cut += cut_here
        if any(b.holes for b in blobs) or mode == modes[-1]:
            break
    return blobs, cut


def _blobs_from_mask(mask: np.ndarray, scale: int, w: int, h: int, params: DetectionParams,
                     img: np.ndarray) -> tuple[list[_Blob], list[_Cut]]:
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hier is None:
        return [], []
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
        return [], []
    cpts = [contours[i][::2, 0, :] for i, _ in cand]  # every other pixel is plenty for a median
    owner = np.repeat(np.arange(len(cand)), [len(c) for c in cpts])
    allp = np.concatenate(cpts)
    strength = group_medians(sobel_magnitude_at(img, allp[:, 0], allp[:, 1]), owner, len(cand))
    strong = [k for k in range(len(cand)) if strength[k] >= params.min_edge_strength]  # else soft shading
    # a shape mostly cut off by the image border has no edge along the border: its own edge's
    # strength is looked at if a rejection needs it (_cut_circle)
    cut = [_Cut(contours[i][:, 0, :], (sw, sh), scale, img) for k, (i, at) in enumerate(cand)
           if at and strength[k] < params.min_edge_strength]
    holes_of = {k: _holes(contours, hier, cand[k][0]) for k in strong}
    to_fit = [cand[k][0] for k in strong] + [j for k in strong for j in holes_of[k]]
    # full-resolution coordinates of every contour to fit, converted in one pass
    pts_of: dict[int, np.ndarray] = {}
    if to_fit:
        full = np.concatenate([contours[i][:, 0, :] for i in to_fit]).astype(float) * scale + (scale - 1) / 2
        pts_of = dict(zip(to_fit, np.split(full, np.cumsum([len(contours[i]) for i in to_fit])[:-1]), strict=True))
    fits = dict(zip(to_fit, ellipses_of([pts_of[i] for i in to_fit]), strict=True))
    out: list[_Blob] = []
    for k in strong:
        i, at_border = cand[k]
        pts = pts_of[i]
        fit = fits[i]
        x, y, bw, bh = cv2.boundingRect(contours[i])
        outline_ok = fit is not None and fit[1] <= params.ellipse_tolerance * min(fit[0].a, fit[0].b) + 0.7 * scale
        if not outline_ok and (at_border or fit is None or not holes_of[k]):
            if at_border:
                cut.append(_Cut(contours[i][:, 0, :], (sw, sh), scale))
            continue
        assert fit is not None
        e, res = fit
        # the contour's extent at full resolution, from its bounding box (the same integers)
        x0, y0 = x * scale + (scale - 1) / 2, y * scale + (scale - 1) / 2
        x1, y1 = (x + bw - 1) * scale + (scale - 1) / 2, (y + bh - 1) * scale + (scale - 1) / 2
        touches = (x0 < margin + scale or y0 < margin + scale
                   or x1 > w - 1 - margin - scale or y1 > h - 1 - margin - scale)
        holes, bent = [], []
        for j in holes_of[k]:
            hf = fits[j]
            if hf is not None and hf[1] < params.ellipse_tolerance * min(hf[0].a, hf[0].b) + 0.7 * scale:
                holes.append((pts_of[j], hf[0]))
            elif hf is not None and not outline_ok:
                bent.append((pts_of[j], hf[0]))
        if outline_ok or holes or bent:
            out.append(_Blob(pts, e, holes, touches, res, scale, outline_ok, bent))
    return out, cut


def _holes(contours: Sequence[np.ndarray], hier: np.ndarray, i: int) -> list[int]:
    """The holes (indices into ``contours``, at least 12 pixels long) of the outer contour ``i``."""
    hs, j = [], hier[i][2]
    while j != -1:
        if len(contours[j]) >= 12:
            hs.append(int(j))
        j = hier[j][0]
    return hs


def _cut_circle(cuts: list[_Cut], params: DetectionParams) -> bool:
    """Whether one of the shapes cut by the image border is a circle's image cut by it: a stretch
    of its outline off the border is an ellipse's arc, at least a quarter of it and of at least
    ``min_radius``, whose ellipse reaches the border (within ``border_margin``). The sheet's edges
    bounding the background beside a sheet cut by the border are not: straight or gently curved
    lines, joined at corners (through a wide lens, k1 -0.28, they bend into arcs like a circle's,
    hence the ellipse that must reach the border, and :func:`_pick_ring` consults this only when
    no whole ring-like shape names the refusal: issue 36, whole rings were refused as cut)."""
    runs: list[np.ndarray] = []
    scales: list[int] = []
    frames: list[tuple[int, int]] = []
    for c in cuts:
        (sw, sh), pts = c.size, c.contour
        inside = (pts[:, 0] > 0) & (pts[:, 1] > 0) & (pts[:, 0] < sw - 1) & (pts[:, 1] < sh - 1)
        if inside.all() or not inside.any():
            continue
        if c.image is not None:
            off = pts[inside][::2]
            if np.median(sobel_magnitude_at(c.image, off[:, 0], off[:, 1])) < params.min_edge_strength:
                continue  # soft shading
        start = int(np.argmin(inside))  # a point on the border: the runs off it do not wrap around
        pts, inside = np.roll(pts, -start, axis=0), np.roll(inside, -start)
        # runs off the border: from a step up (i + 1) to the next step down (i), closed by a last False
        steps = np.flatnonzero(np.diff(np.r_[inside, False].astype(np.int8)))
        new = [pts[a + 1:b + 1].astype(float) * c.scale + (c.scale - 1) / 2
               for a, b in zip(steps[::2], steps[1::2], strict=True) if b - a >= 12]
        runs += new
        scales += [c.scale] * len(new)
        frames += [(sw * c.scale, sh * c.scale)] * len(new)
    for run, scale, frame, fit in zip(runs, scales, frames, ellipses_of(runs), strict=True):
        if fit is None:
            continue
        e, res = fit
        arc = float(np.sum(np.hypot(*np.diff(run, axis=0).T)))
        if (res <= params.ellipse_tolerance * min(e.a, e.b) + 0.7 * scale and min(e.a, e.b) >= params.min_radius
                and arc >= 0.25 * e.perimeter and room_to_border(e, frame) < params.border_margin + scale):
            return True
    return False


def _edge(gray: np.ndarray, ellipse: Ellipse, params: DetectionParams) -> EdgeFit:
    return refine_edge(gray, ellipse.to_conic(), spacing=params.edge_spacing, max_width=params.max_blur,
                       curvature_correction=params.curvature_correction)


def _ring_edges(work: np.ndarray, ring: _Ring, params: DetectionParams) -> tuple[EdgeFit, EdgeFit]:
    """The outer and inner edge of the ring picked: along the traced contours if the lens bends
    it (``ring.bent``, :func:`.contour_edges.refine_along_contour`), else along the ellipses'
    normals (:func:`refine_edge`) with the points off the traced edge dropped
    (:func:`.contour_edges.keep_on_traced`)."""
    b = ring.blob
    curves = ((b.contour, b.ellipse), (ring.hole_pts, ring.hole))
    if ring.bent:
        return tuple(refine_along_contour(work, c, spacing=params.edge_spacing, max_width=params.max_blur,  # type: ignore[return-value]
                                          curvature_correction=params.curvature_correction, room=min(e.a, e.b))
                     for c, e in curves)
    outer, inner = (keep_on_traced(work, _edge(work, e, params), c, min(e.a, e.b), params.edge_spacing,
                                   params.max_blur, params.curvature_correction) for c, e in curves)
    return outer, inner


def detect_target(image: np.ndarray, target: Target, params: DetectionParams = DEFAULT_PARAMS,
                  name: str = "", checkerboard: bool = True) -> Detection:
    """Detect ``target`` in a grey (or BGR) image. Never raises for image content: a view that
    cannot be used comes back with ``reason`` set."""
    gray = to_float(image)
    h, w = gray.shape
    det = Detection(w, h, name=name)
    if gray.size == 0 or (image.dtype.kind == "f" and not np.isfinite(gray).all()):  # integers are finite
        return det.refuse(DetectionRefusal.UNREADABLE_IMAGE, "empty or invalid image")
    if min(h, w) < 16:
        return det.refuse(DetectionRefusal.UNREADABLE_IMAGE, f"image too small ({w}x{h})")
    if grey_range(image, gray) < 20:
        return det.refuse(DetectionRefusal.NO_CONTRAST, "no contrast in the image (lens cap, exposure?)")
    work = gray
    if params.gamma != 1.0:
        work = (255.0 * (np.clip(gray, 0, 255) / 255.0) ** params.gamma).astype(np.float32)
    if target.grids:
        return _detect_grids(gray, work, target, params, det)
    # blobs are rings and discs; a checkerboard alone does not need them (half its time at 800x600)
    blobs, cut_shapes = find_blobs(gray, params) if target.rings or target.discs else ([], [])
    if target.rings:
        try:
            ring = _pick_ring(blobs, target, params, cut_shapes)
        except _Reject as r:
            return det.refuse(r.kind, str(r))
        try:
            outer, inner = _ring_edges(work, ring, params)
        except EdgeError as exc:
            return det.refuse(exc.kind, f"ring{' (traced outline)' if ring.bent else ''}: {exc}")
        det.edges.append(CircleEdge(0, outer.points, outer.conic, float(np.median(outer.width)), outer.rms))
        det.edges.append(CircleEdge(1, inner.points, inner.conic, float(np.median(inner.width)), inner.rms))
        if target.discs:
            disc_idx = 2 * len(target.rings)
            try:
                disc_blob = _pick_disc(blobs, (ring.blob, ring.hole), target, params, cut_shapes)
                fit = _edge(work, disc_blob.ellipse, params)
                det.edges.append(CircleEdge(disc_idx, fit.points, fit.conic, float(np.median(fit.width)), fit.rms))
            except (_Reject, EdgeError) as exc:
                return det.refuse(exc.kind, f"disc: {exc}")
    elif target.discs:
        return det.refuse(DetectionRefusal.UNSUPPORTED, "targets without a ring are not supported by the detector yet")
    if checkerboard and target.boards:
        from .board_corners import find_board_corners

        grey8 = image if image.ndim == 2 and image.dtype == np.uint8 else np.clip(gray, 0, 255).astype(np.uint8)
        corners = find_board_corners(grey8, target, det)
        if corners is None and not target.rings:
            return det if det.reason else det.refuse(DetectionRefusal.NO_TARGET, f"{target.boards[0].kind} not found")
        det.corners = corners
    return det


class _Reject(Exception):
    """A feature refused: its kind and the words (the exception's text)."""

    def __init__(self, kind: DetectionRefusal, message: str) -> None:
        super().__init__(message)
        self.kind = kind


def _detect_grids(gray: np.ndarray, work: np.ndarray, target: Target, params: DetectionParams,
                  det: Detection) -> Detection:
    from .grids import GridError, detect_grid

    # a disc grid has no holes: the Otsu pass could only be discarded, go straight to the adaptive one
    modes = ("adaptive",) if all(g.kind == "disc" for g in target.grids) else ("otsu", "adaptive")
    blobs, _ = find_blobs(gray, replace(params, min_radius=min(params.min_radius, 4.0)), modes)
    blobs = [b for b in blobs if b.outline_ok]
    notes = []
    for gi in range(len(target.grids)):
        try:
            edges, note = detect_grid(work, blobs, target, gi, max_blur=params.max_blur, spacing=params.edge_spacing,
                                      curvature_correction=params.curvature_correction)
        except GridError as e:
            return det.refuse(e.kind, str(e))
        det.edges += [CircleEdge(i, p, c, w, r) for i, p, c, w, r in edges]
        if note:
            notes.append(note)
    n_elem = len({e.circle for e in det.edges if target.circles[e.circle].dark_inside})
    if n_elem < 6:
        det.refuse(DetectionRefusal.TOO_FEW_FEATURES, f"only {n_elem} grid element(s) measured; need 6")
    det.note = "; ".join(notes)
    return det


# how far past the detector's limits (outline's ellipse residual, concentricity spread) a whole
# ring-like shape is still measured along its traced contours: the study `undesigned_views` saw
# 1.1-1.3x (outline) and up to 2.0x (spread) within the guide's 70 deg tilt, 1.1-7.2x beyond it; a
# square with the ring's hole gives 2.6-2.8x (test_detect): a stopgap until the traced outline's
# own smoothness is tested
BENT_OUTLINE = 2.0
BENT_SPREAD = 2.5


@dataclass(frozen=True)
class _Ring:
    """The ring picked: its blob, its hole's traced contour (N, 2) and ellipse, and whether the
    lens bends it off the conics the ellipse path assumes (``bent``: its outline or hole is no
    ellipse, or the two are not concentric circles' images; its edges follow the traced contours,
    :mod:`.contour_edges`)."""

    blob: _Blob
    hole_pts: np.ndarray
    hole: Ellipse
    bent: bool = False


def _pick_ring(blobs: list[_Blob], target: Target, params: DetectionParams, cut_shapes: list[_Cut] | None = None
               ) -> _Ring:
    """The blob that is the target's ring and its hole, or :class:`_Reject` naming why none is:
    cut by the border, too small, ambiguous, or no ring-like shape at all. A ring-like shape whole
    in the image whose outline or hole is no ellipse, or whose two are not concentric circles'
    images (a close ring through a wide lens, issue 36) is picked, ``bent``, when no conic ring is
    in view: its edges are then measured along its traced contours."""
    ring = target.rings[0]
    ratio = ring.inner_radius / ring.outer_radius
    near = 0.35 + 5 * params.ellipse_tolerance  # how far the hole's relative size may be from the printed one
    cands: list[tuple[float, _Blob, np.ndarray, Ellipse]] = []
    bent_cands: list[tuple[float, _Blob, np.ndarray, Ellipse]] = []  # whole ring-like shapes off conics
    cut = False
    small = 0.0  # the narrowest semi-axis of a ring too small to measure
    bent = 0.0  # the largest spread of a ring-like shape whose outline and hole are not concentric circles' images
    outline = 0.0  # the largest ellipse residual (over its limit) of a ring-like shape's outline
    for b in blobs:
        size = np.sqrt(b.ellipse.a * b.ellipse.b)
        wide = min(b.ellipse.a, b.ellipse.b) >= params.min_radius
        for hp, he in b.bent_holes:
            if not b.touches_border and abs(np.sqrt(he.a * he.b) / size / ratio - 1) < near:
                # outline and hole both bent (a close ring through a wide lens): the outline's figure
                fig = b.fit_residual / (params.ellipse_tolerance * min(b.ellipse.a, b.ellipse.b) + 0.7 * b.scale)
                outline = max(outline, fig)
                if wide and fig <= BENT_OUTLINE:
                    bent_cands.append((size, b, hp, he))
        for hp, he in b.holes:
            if b.touches_border:  # the outline is cut: its ellipse says little beyond the hole's size
                cut |= bool(abs(np.sqrt(he.a * he.b) / size / ratio - 1) < near)
                continue
            # concentric whatever the perspective; the contours' ellipses are uncertain by a few
            # pixels (threshold level, blur, the pixel grid), much of a small hole's shape
            spread, r = concentric_fit(b.ellipse, he)
            if abs(r / ratio - 1) >= near:
                continue
            if not b.outline_ok:  # an elliptical hole in a shape whose outline is no ellipse
                fig = b.fit_residual / (params.ellipse_tolerance * min(b.ellipse.a, b.ellipse.b) + 0.7 * b.scale)
                outline = max(outline, fig)
                if wide and fig <= BENT_OUTLINE:
                    bent_cands.append((size, b, hp, he))
                continue
            limit = 4 * params.ellipse_tolerance + 8 * b.scale / min(he.a, he.b)
            if spread >= limit:
                bent = max(bent, spread / limit)
                if wide and spread <= BENT_SPREAD * limit:
                    bent_cands.append((size, b, hp, he))
                continue
            if not wide:
                small = max(small, min(b.ellipse.a, b.ellipse.b))
                continue
            cands.append((size, b, hp, he))
    if not cands and bent_cands and not small:
        cands, is_bent = bent_cands, True
    else:
        is_bent = False
    if not cands:
        # a circle's arc leaving the frame elsewhere names the refusal only when no whole ring-like
        # shape says more; a hole in a shape joined to the background: the ring's outline is lost
        seen = bool(small or bent or outline)
        _refuse_ring(cut or (not seen and _cut_circle(cut_shapes or [], params)), small, bent, outline, params)
    if len(cands) > 1:
        cands.sort(key=lambda c: -c[0])
        if cands[1][0] > 0.7 * cands[0][0]:
            raise _Reject(DetectionRefusal.AMBIGUOUS,
                          f"{len(cands)} ring-like shapes of similar size in view: ambiguous")
    return _Ring(cands[0][1], cands[0][2], cands[0][3], is_bent)


def _refuse_ring(cut: bool, small: float, bent: float, outline: float, params: DetectionParams) -> None:
    """Raise the refusal of a view without a measurable ring, the feature's own reason first: a
    ring-like shape (or a circle's arc) at the border, one too small, one that is not the image of
    concentric circles, one whose outline is no ellipse (the figures: over the detector's limit),
    else no ring-like shape at all."""
    if cut:
        raise _Reject(DetectionRefusal.CUT_BY_BORDER, "ring cut by the image border (keep the whole ring in view)")
    if small:
        raise _Reject(DetectionRefusal.TOO_SMALL, f"ring too small ({2 * small:.0f} px across at its narrowest; "
                      f"at least {2 * params.min_radius:.0f} px)")
    if bent:
        raise _Reject(DetectionRefusal.NOT_CONCENTRIC,
                      f"ring not the image of concentric circles ({bent:.1f}x the detector's limit): the lens "
                      "bends a close ring or one near the border of a wide lens; hold it farther or nearer "
                      "the centre (a fisheye: distortion_model:=equidistant)")
    if outline:
        raise _Reject(DetectionRefusal.OUTLINE_NOT_ELLIPSE,
                      f"ring's outline not an ellipse ({outline:.1f}x the detector's limit): the lens bends "
                      "a close ring or one near the border of a wide lens, or something covers its edge; hold "
                      "it farther or nearer the centre (a fisheye: distortion_model:=equidistant)")
    raise _Reject(DetectionRefusal.NO_TARGET, "no ring found")


def _pick_disc(blobs: list[_Blob], ring: tuple[_Blob, Ellipse], target: Target, params: DetectionParams,
               cut_shapes: list[_Cut] | None = None) -> _Blob:
    """The blob that is the target's disc: its size and distance from the ring's centre, relative
    to the ring's size, as printed once the perspective's scale at either is divided out
    (:func:`_perspective_scale`), within a factor 1.8 each (the tilt's foreshortening, the lens)."""
    ring_blob = ring[0]
    printed, disc = target.rings[0], target.discs[0]
    size_ratio = disc.radius / printed.outer_radius
    dist_ratio = np.hypot(disc.center[0] - printed.center[0], disc.center[1] - printed.center[1]) / printed.outer_radius
    rs = np.sqrt(ring_blob.ellipse.a * ring_blob.ellipse.b)
    scale_at, centre = _perspective_scale(*ring)
    best: tuple[float, _Blob] | None = None
    cut = False
    for b in blobs:
        size = np.sqrt(b.ellipse.a * b.ellipse.b)
        if b is ring_blob or not b.outline_ok or any(np.sqrt(e.a * e.b) > 0.2 * size for _, e in b.holes):
            continue
        if size < params.min_radius or b.fit_residual > 2 / 3 * params.ellipse_tolerance * size + 0.7:
            continue
        q = scale_at(b.ellipse.cx, b.ellipse.cy)
        if q <= 0:
            continue  # beyond the plane's horizon
        sr = size / rs / q**1.5
        dr = np.hypot(b.ellipse.cx - centre[0], b.ellipse.cy - centre[1]) / rs / q
        score = abs(np.log(sr / size_ratio)) + abs(np.log(dr / dist_ratio))
        if abs(np.log(sr / size_ratio)) > 0.6 or abs(np.log(dr / dist_ratio)) > 0.6:
            continue
        if b.touches_border:
            cut = True
            continue
        if best is None or score < best[0]:
            best = (score, b)
    if best is None:
        # a disc-like blob at the border, or a circle's arc leaving the frame (the ring is whole)
        if cut or _cut_circle(cut_shapes or [], params):
            raise _Reject(DetectionRefusal.CUT_BY_BORDER, "disc cut by the image border")
        raise _Reject(DetectionRefusal.NO_TARGET, "no disc found beside the ring")
    return best[1]


def _perspective_scale(ring_blob: _Blob, hole: Ellipse) -> tuple[Callable[[float, float], float], np.ndarray]:
    """How the target plane's image scale at a pixel compares with that at the ring's centre, and
    the image of that centre. The ring's two ellipses give the centre's image c and the plane's
    vanishing line l = C_out c (:mod:`..geometry.circular`). A plane's homography scales areas
    near a pixel x by (l.x)^3 (x = (u, v, 1)), so with q = l.x / l.c a circle at x looks q^1.5
    times as large as at c, and a segment from c to x is q times as long as at c's scale (along
    a line the map is a 1-D homography: lengths scale by the product of the ends' l.x). Close,
    tilted views change the disc's apparent size against the ring's by 2x and more. Returns q
    (1 everywhere if the ellipses give no centre) and c."""
    C = ring_blob.ellipse.to_conic()
    try:
        c = centre_image_from_ring(C, hole.to_conic())
    except (CircularPointError, np.linalg.LinAlgError):
        e = ring_blob.ellipse
        return (lambda x, y: 1.0), np.array([e.cx, e.cy, 1.0])
    line = C @ c
    at_c = float(line @ c)
    return (lambda x, y: float(line[0] * x + line[1] * y + line[2]) / at_c), c
