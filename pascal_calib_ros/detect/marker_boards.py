"""Corners of a ChArUco board or a Kalibr AprilGrid, in the board's corner order, partial views
included.

1. Markers by OpenCV's aruco detector (``cv2.aruco.ArucoDetector``; an AprilGrid's tag36h11 with
   ``markerBorderBits = 2``). Markers whose id is not on the board (another board or other tags in
   view, the wrong dictionary or ``first_id``) and markers that disagree with their neighbours
   (each neighbour's homography, from its own four corners, predicts where a marker's centre must
   be) are left out, and the note says which; an id seen twice (two boards in view) refuses the
   view, since which copy a marker belongs to cannot be told.
2. Corner estimates: a ChArUco's inner corners interpolated from the markers by OpenCV
   (``CharucoDetector.detectBoard``, as ``camera_calibration`` does); an AprilGrid's four corners
   per tag from the tag's quad (Kalibr's order, :meth:`AprilGrid.tag_corner_indices`).
3. Every corner refined at full resolution as the centre of point symmetry of the image
   (:mod:`.saddle`, the checkerboard path's refinement) over a disc that holds only the corner's
   own two edges: ``RADIUS_FRACTION`` of the board's ``corner_clearance`` imaged through the
   nearest marker's homography. A corner about which the image is not point-symmetric like the
   board's other corners (an occluder, glare, the board's edge cut by the image border) is NaN.
4. A view counts when it has at least ``MIN_CORNERS`` corners spread over two directions of the
   board (``MIN_SPREAD`` corner spacings of standard deviation across the thinner one); a board seen
   mirrored (found only in the flipped image) is refused with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from ..target_boards import AprilGrid, CharucoBoard, MarkerBoard, aruco_dictionary
from .detection import Detection, DetectionRefusal
from .saddle import SaddleFit, refine_saddles

MIN_CORNERS = 6  # a view with fewer measured corners is refused (camera_calibration asks as many)
MIN_SPREAD = 0.5  # ... or with their spread across the board's thinner direction below this many spacings
RADIUS_FRACTION = 0.7  # a corner is refined over a disc of this fraction of its clearance ...
MIN_RADIUS, MAX_RADIUS = 2.0, 12.0  # ... px, within these bounds
MAX_NEIGHBOUR_ERROR = 0.5  # a marker more than this fraction of its side from where its neighbours put it is dropped
MAX_ASYMMETRY, MIN_SYMMETRY, MIN_SPREAD_GREY = 3.0, 0.5, 0.3  # the checkerboard path's saddle checks


@dataclass(frozen=True)
class Markers:
    """Markers found in a view: ids (M,) and corners (M, 4, 2) px in the detector's order."""

    ids: np.ndarray
    corners: np.ndarray

    def take(self, keep: np.ndarray) -> Markers:
        return Markers(self.ids[keep], self.corners[keep])


@lru_cache(maxsize=8)
def aruco_detector(board: MarkerBoard) -> Any:
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = board.border_bits
    return cv2.aruco.ArucoDetector(aruco_dictionary(board.dictionary), params)


@lru_cache(maxsize=8)
def charuco_detector(board: CharucoBoard) -> Any:
    ids = np.arange(board.first_id, board.first_id + int((board.marker_ids >= 0).sum()), dtype=np.int32)
    cv_board = cv2.aruco.CharucoBoard(board.squares, board.square_size, board.marker_size,
                                      aruco_dictionary(board.dictionary), ids)
    cv_board.setLegacyPattern(board.legacy)
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = board.border_bits
    return cv2.aruco.CharucoDetector(cv_board, cv2.aruco.CharucoParameters(), params)


def detect_markers(gray8: np.ndarray, board: MarkerBoard) -> Markers:
    """Every marker of the board's dictionary in the image (any id)."""
    corners, ids, _ = aruco_detector(board).detectMarkers(gray8)
    if ids is None or not len(ids):
        return Markers(np.zeros(0, int), np.zeros((0, 4, 2)))
    return Markers(np.asarray(ids, int).ravel(), np.asarray(corners, float).reshape(-1, 4, 2))


def _homographies(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(M, 3, 3) homographies from four points each, src (M, 4, 2) -> dst (M, 4, 2)."""
    return np.stack([cv2.getPerspectiveTransform(s.astype(np.float32), d.astype(np.float32))
                     for s, d in zip(src, dst, strict=True)])


def _apply(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = np.c_[p, np.ones(len(p))] @ H.T
    return q[:, :2] / q[:, 2:3]


def filter_markers(markers: Markers, board: MarkerBoard, notes: list[str]) -> Markers:
    """The markers that belong to the board: on it, seen once, where their neighbours put them."""
    layout = board.marker_corners()
    on_board = np.array([int(k) in layout for k in markers.ids], bool)
    if not on_board.all():
        notes.append(f"markers not on this board left out (ids {sorted(set(markers.ids[~on_board].tolist()))[:8]})")
    m = markers.take(on_board)
    ids, counts = np.unique(m.ids, return_counts=True)
    if (counts > 1).any():  # which copy a marker belongs to cannot be told: none is used
        notes.append(f"marker ids seen more than once ({ids[counts > 1].tolist()[:8]}): two boards in view?")
        return m.take(np.zeros(len(m.ids), bool))
    if len(m.ids) < 2:
        return m
    obj = np.stack([layout[int(k)] for k in m.ids])
    H = _homographies(obj, m.corners)
    centre_obj, centre_img = obj.mean(1), m.corners.mean(1)
    side = np.linalg.norm(np.diff(m.corners, axis=1, append=m.corners[:, :1]), axis=2).mean(1)
    reach = 3 * float(np.max(np.linalg.norm(np.diff(obj, axis=1), axis=2)))  # the next markers but one
    bad = np.zeros(len(m.ids), bool)
    for i in range(len(m.ids)):
        near = np.flatnonzero((np.linalg.norm(centre_obj - centre_obj[i], axis=1) < reach)
                              & (np.arange(len(m.ids)) != i))
        if len(near) < 2:
            continue
        pred = np.array([_apply(H[j], centre_obj[i:i + 1])[0] for j in near])
        bad[i] = np.median(np.linalg.norm(pred - centre_img[i], axis=1)) > MAX_NEIGHBOUR_ERROR * side[i]
    if bad.any():
        notes.append(f"markers not where their neighbours put them left out (ids {m.ids[bad].tolist()[:8]})")
    return m.take(~bad)


def corner_estimates(gray8: np.ndarray, board: MarkerBoard, markers: Markers) -> np.ndarray:
    """(N, 2) first estimates of the board's corners, NaN where the markers do not give one."""
    n = len(board.corner_points())
    out = np.full((n, 2), np.nan)
    if not len(markers.ids):
        return out
    if isinstance(board, AprilGrid):
        for k, c in zip(markers.ids, markers.corners, strict=True):
            out[board.tag_corner_indices(int(k))[[1, 0, 3, 2]]] = c
        return out
    corners, ids, _, _ = charuco_detector(board).detectBoard(
        gray8, markerCorners=tuple(c.reshape(1, 4, 2).astype(np.float32) for c in markers.corners),
        markerIds=markers.ids.reshape(-1, 1).astype(np.int32))
    if ids is not None and len(ids):
        out[np.asarray(ids, int).ravel()] = np.asarray(corners, float).reshape(-1, 2)
    return out


def corner_radii(board: MarkerBoard, markers: Markers, seen: np.ndarray) -> np.ndarray:
    """(N,) px disc radius per corner: ``RADIUS_FRACTION`` of the clearance, imaged by the
    homography of the marker nearest to the corner on the board (its smaller singular value)."""
    layout = board.marker_corners()
    obj = np.stack([layout[int(k)] for k in markers.ids])
    H = _homographies(obj, markers.corners)
    pts = board.corner_points()[seen]
    nearest = np.argmin(np.linalg.norm(pts[:, None] - obj.mean(1)[None], axis=2), axis=1)
    eps = 1e-4 * board.corner_spacing
    scale = np.empty(len(pts))
    for k, (p, j) in enumerate(zip(pts, nearest, strict=True)):
        q = _apply(H[j], p + np.array([[0.0, 0.0], [eps, 0.0], [0.0, eps]]))
        J = np.stack([q[1] - q[0], q[2] - q[0]], 1) / eps
        scale[k] = np.linalg.svd(J, compute_uv=False)[-1]
    return np.clip(RADIUS_FRACTION * board.corner_clearance * scale, MIN_RADIUS, MAX_RADIUS)


def _on_saddle(fit: SaddleFit) -> np.ndarray:
    """As the checkerboard path: about as point-symmetric as the board's clean corners, an
    X-junction at all, and with about the board's contrast."""
    return ((fit.rms <= MAX_ASYMMETRY * np.percentile(fit.rms, 25)) & (fit.symmetry >= MIN_SYMMETRY)
            & (fit.spread >= MIN_SPREAD_GREY * np.median(fit.spread)))


def _mirrored(gray8: np.ndarray, board: MarkerBoard, found: int) -> bool:
    """Whether the flipped image shows clearly more of the board's markers than the image."""
    flipped = detect_markers(np.ascontiguousarray(gray8[:, ::-1]), board)
    layout = board.marker_corners()
    on_board = sum(int(k) in layout for k in flipped.ids)
    return on_board >= 4 and on_board > 2 * found


def spread_ok(board: MarkerBoard, seen: np.ndarray) -> bool:
    """Whether the measured corners span two directions of the board (not one row)."""
    p = board.corner_points()[seen]
    if len(p) < 3:
        return False
    s = np.linalg.svd(p - p.mean(0), compute_uv=False) / np.sqrt(len(p))
    return bool(s[-1] >= MIN_SPREAD * board.corner_spacing)


def find_marker_board(gray8: np.ndarray, board: MarkerBoard, det: Detection | None = None) -> np.ndarray | None:
    """(N, 2) corners in the board's order, NaN for corners not seen or not on a saddle, or None
    when the view does not count (``det.reason`` says why; ``det.note`` what was left out)."""
    notes: list[str] = []
    found = detect_markers(gray8, board)
    markers = filter_markers(found, board, notes)
    if det is not None:
        det.marker_ids, det.marker_corners = markers.ids.copy(), markers.corners.copy()
    if len(markers.ids) < 2 and _mirrored(gray8, board, len(markers.ids)):
        return _refuse(det, f"{board.kind} board seen mirrored (a flipped image, or the board printed mirrored?)",
                       notes, DetectionRefusal.MIRRORED)
    if not len(markers.ids):
        why = "no marker of this board found" if not notes else notes[-1]
        return _refuse(det, f"{board.kind}: {why}", notes, DetectionRefusal.NO_TARGET)
    est = corner_estimates(gray8, board, markers)
    seen = np.all(np.isfinite(est), 1)
    out = np.full_like(est, np.nan)
    if seen.sum() >= 4:
        rho = corner_radii(board, markers, seen)
        fit = refine_saddles(gray8, est[seen], rho)
        ok = _on_saddle(fit)
        idx = np.flatnonzero(seen)
        out[idx[ok]] = fit.points[ok]
        if det is not None:
            det.corners_rejected = int((~ok).sum())
        if (~ok).any():
            notes.append(f"{int((~ok).sum())} of {int(seen.sum())} corners not on a saddle left out")
    measured = np.all(np.isfinite(out), 1)
    if measured.sum() < MIN_CORNERS:
        return _refuse(det, f"{board.kind}: {int(measured.sum())} corners measured; need {MIN_CORNERS}", notes,
                       DetectionRefusal.TOO_FEW_FEATURES)
    if not spread_ok(board, measured):
        return _refuse(det, f"{board.kind}: the {int(measured.sum())} corners seen lie along one row of the board; "
                            "show more of it", notes, DetectionRefusal.TOO_FEW_FEATURES)
    if det is not None and notes:
        det.note = "; ".join([det.note, *notes]) if det.note else "; ".join(notes)
    return out


def _refuse(det: Detection | None, reason: str, notes: list[str], kind: DetectionRefusal) -> np.ndarray | None:
    """None, the view refused with ``kind`` and ``reason`` (and what was left out) on ``det``."""
    if det is not None:
        det.refuse(kind, reason)
        if notes:
            det.note = "; ".join(notes)
    return None
