"""Whether a candidate view's circles image as the ellipses the detector accepts.

The detector (:mod:`..detect.target_detector`, :mod:`..detect.grids`) finds a circle as a dark
blob whose outline an ellipse fits: the median |Sampson distance| of the outline to its
algebraic ellipse at most ``tol * b + 0.7 s`` px (``tol`` the ellipse tolerance of
:class:`..detect.detection.DetectionParams` for the lens, b the semi-minor axis, s the downscale
of the image the outlines are traced in), a disc's at most ``2/3 tol sqrt(a b) + 0.7``; and a
ring as an outline and a hole whose ellipses pass the concentric test
(:func:`..detect.grids.concentric_fit`: spread below ``4 tol + 8 s / b_hole``). A pinhole's
image of a circle is an ellipse exactly; radial distortion bends it, most where the image
scale changes fastest (near the border of a wide lens) and over the largest images (a close
ring): there a whole ring, well inside the image, is not an ellipse the detector accepts.

:func:`shape_shares` images every ring, every disc and the corner elements of every grid under
the camera (the current estimate, for a candidate), fits them as the detector does and returns
the largest share of a limit used: at most 1 the detector can accept the view, and the guide
keeps a margin below (:attr:`.candidates.Feasibility.shape_share`) for the outline's pixel
noise, the person's placement error and the estimate's own error.
"""

from __future__ import annotations

import numpy as np

from ...detect import DetectionParams
from ...geometry import Camera, ImageSize, ellipses_from_conics, fit_conics_algebraic
from ...targets import Target

POINTS = 64  # points per imaged circle (the median is weighted by the arc each stands for)
RING, HOLE, DISC, ELEMENT = 0, 1, 2, 3


def contour_scale(size: ImageSize, params: DetectionParams) -> int:
    """The detector's downscale for its outline search: halved (``cv2.pyrDown``, sizes rounded
    up) until at most ``params.working_pixels`` pixels remain."""
    width, height = size
    s, w, h = 1, width, height
    while w * h > params.working_pixels:
        w, h, s = (w + 1) // 2, (h + 1) // 2, 2 * s
    return s


def shape_circles(target: Target) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The circles checked: centres (K, 2), radii (K,), kinds (K,: RING, HOLE, DISC, ELEMENT) and the
    ring pairs (outer, hole) as indices; a grid's elements at the corners of its layout (the
    ones that reach farthest into the image's border)."""
    ctr: list[tuple[float, float]] = []
    rad: list[float] = []
    kind: list[int] = []
    pairs: list[tuple[int, int]] = []
    for r in target.rings:
        pairs.append((len(ctr), len(ctr) + 1))
        ctr += [r.center, r.center]
        rad += [r.outer_radius, r.inner_radius]
        kind += [RING, HOLE]
    for d in target.discs:
        ctr.append(d.center)
        rad.append(d.radius)
        kind.append(DISC)
    for g in target.grids:
        for c in g.centers()[[0, g.cols - 1, -g.cols, -1]]:
            ctr.append(c)
            rad.append(g.outer_radius)
            kind.append(ELEMENT)
            if g.kind == "ring" and g.inner_radius > 0:
                ctr.append(c)
                rad.append(g.inner_radius)
                kind.append(HOLE)
    return (np.array(ctr, float).reshape(-1, 2), np.array(rad, float), np.array(kind, int), pairs)


def _weighted_median(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Median along the last axis of x weighted by w (same shape)."""
    order = np.argsort(x, axis=-1)
    xs, ws = np.take_along_axis(x, order, -1), np.take_along_axis(w, order, -1)
    cw = np.cumsum(ws, -1)
    k = np.argmax(cw >= cw[..., -1:] / 2, axis=-1)
    return np.take_along_axis(xs, k[..., None], -1)[..., 0]


def shape_shares(target: Target, camera: Camera, R: np.ndarray, t: np.ndarray,
                 params: DetectionParams | None = None) -> np.ndarray:
    """Per pose (R (C, 3, 3), t (C, 3), target YAML frame -> camera) the largest share of a
    detector limit (module docstring) any checked circle uses: the weighted median |Sampson
    distance| d of its image to its fitted ellipse over ``tol b + 0.7 s`` (discs: also over
    ``2/3 tol sqrt(ab) + 0.7``), a ring's spread over ``4 tol + 8 s / b_hole``; inf where a circle
    does not image (behind the camera, a folding lens)."""
    params = params or DetectionParams.for_lens(camera.lens.wide)
    tol, s = params.ellipse_tolerance, contour_scale(camera.size, params)
    ctr, rad, kind, pairs = shape_circles(target)
    C, K = len(R), len(ctr)
    if not C or not K:
        return np.zeros(C)
    a = np.linspace(0, 2 * np.pi, POINTS, endpoint=False)
    P = (ctr[:, None, :] + rad[:, None, None] * np.stack([np.cos(a), np.sin(a)], -1)).reshape(-1, 2)
    X = np.swapaxes(R[:, :, :2] @ P.T, 1, 2) + t[:, None, :]
    flat = X.reshape(-1, 3)
    img = np.full((len(flat), 2), np.nan)
    ok = np.ones(len(flat), bool) if camera.lens.wide else flat[:, 2] > 1e-6
    img[ok] = camera.project(flat[ok])
    uv = img.reshape(C * K, POINTS, 2)
    good = np.all(np.isfinite(uv), axis=(1, 2))
    uv[~good] = np.c_[np.cos(a), np.sin(a)]  # a placeholder circle: its share is set to inf below
    owner = np.repeat(np.arange(C * K), POINTS)
    conics, fit_ok = fit_conics_algebraic(uv.reshape(-1, 2), owner, C * K)
    par, real = ellipses_from_conics(conics)
    good &= fit_ok & real
    Xh = np.concatenate([uv, np.ones((C * K, POINTS, 1))], 2)
    CX = Xh @ conics  # Sampson distance x'Cx / (2 |(Cx)_xy|), as :func:`..geometry.conic.sampson_distances`
    d = np.abs(np.sum(CX * Xh, 2)) / np.maximum(2 * np.linalg.norm(CX[:, :, :2], axis=2), 1e-300)
    seg = np.linalg.norm(np.roll(uv, -1, 1) - uv, axis=2)
    arc = (seg + np.roll(seg, 1, 1)) / 2
    med = _weighted_median(d, arc)
    semi = np.minimum(np.abs(par[:, 2]), np.abs(par[:, 3]))
    share = med / (tol * semi + 0.7 * s)
    kinds = np.tile(kind, C)
    disc = kinds == DISC
    disc_size = np.sqrt(np.abs(par[disc, 2] * par[disc, 3]))
    share[disc] = np.maximum(share[disc], med[disc] / (2 / 3 * tol * disc_size + 0.7))
    share = np.where(good, share, np.inf).reshape(C, K)
    par = par.reshape(C, K, 5)
    for o, h in pairs:  # the detector's concentric test of a ring's outline and hole
        hole_b = np.minimum(np.abs(par[:, h, 2]), np.abs(par[:, h, 3]))
        share[:, o] = np.maximum(share[:, o], concentric_spreads(par[:, o], par[:, h]) / (4 * tol + 8 * s / hole_b))
    return np.where(np.isfinite(share).all(1), share.max(1), np.inf)


def _unit_conics(cx: np.ndarray, cy: np.ndarray, a: np.ndarray, b: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Conics (N, 3, 3) of ellipses, each scaled to the value -1 at its centre."""
    c, s = np.cos(ang), np.sin(ang)
    ia, ib = 1 / (a * a), 1 / (b * b)
    p, q, r = c * c * ia + s * s * ib, c * s * (ia - ib), s * s * ia + c * c * ib
    u, v = -(p * cx + q * cy), -(q * cx + r * cy)
    return np.stack([np.stack([p, q, u], -1), np.stack([q, r, v], -1),
                     np.stack([u, v, -(u * cx + v * cy) - 1], -1)], -2)


def concentric_spreads(outer: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """:func:`..detect.grids.concentric_fit`'s spread for many ellipse pairs (N, 5) (cx, cy, a, b,
    angle) at once: with Co and Ch the conics in the outer ellipse's frame scaled by its size
    sqrt(ab), |eig(Co^-1 Ch)| sorted w0 <= w1 <= w2, spread = (w2 - w1) / ((w1 + w2) / 2) (0 for
    the image of two concentric circles, whatever the view); inf where undefined."""
    sz = np.sqrt(np.abs(outer[:, 2] * outer[:, 3]))
    z = np.zeros(len(outer))
    Co = _unit_conics(z, z, outer[:, 2] / sz, outer[:, 3] / sz, outer[:, 4])
    Ch = _unit_conics((hole[:, 0] - outer[:, 0]) / sz, (hole[:, 1] - outer[:, 1]) / sz, hole[:, 2] / sz,
                     hole[:, 3] / sz, hole[:, 4])
    with np.errstate(all="ignore"):
        good = np.isfinite(Co).all((1, 2)) & np.isfinite(Ch).all((1, 2)) & (np.abs(np.linalg.det(Co)) > 1e-300)
        w = np.sort(np.abs(np.linalg.eigvals(np.linalg.solve(np.where(good[:, None, None], Co, np.eye(3)),
                                                             np.where(good[:, None, None], Ch, np.eye(3))))), 1)
        pair = (w[:, 1] + w[:, 2]) / 2
        spread = (w[:, 2] - w[:, 1]) / pair
    return np.where(good & np.isfinite(spread) & (pair > 0), spread, np.inf)


__all__ = ["concentric_spreads", "contour_scale", "shape_circles", "shape_shares"]
