"""One view's observations for the refinement: edge points with their circles, checkerboard corners."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...detect import Detection
from ...targets import Target


@dataclass
class ViewData:
    """One view's observations in the target's local frame (origin at the first circle centre)."""

    points: np.ndarray  # (N, 2) edge pixels
    centers: np.ndarray  # (N, 2) circle centre of each point, local frame
    radii: np.ndarray  # (N,)
    signs: np.ndarray  # (N,) +1 dark inside, -1 dark outside
    circle_ids: np.ndarray  # (N,) index into Target.circles
    corners: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) pixels
    corner_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) local frame
    # observations the refinement rejected as outliers so far (not in the arrays above)
    rejected_edges: int = 0
    rejected_corners: int = 0

    def without(self, edge_rows: np.ndarray, corner_rows: np.ndarray) -> ViewData:
        """A copy without the given edge points and corners (bool masks), counting them as rejected."""
        keep_e, keep_c = ~np.asarray(edge_rows, bool), ~np.asarray(corner_rows, bool)
        return ViewData(points=self.points[keep_e], centers=self.centers[keep_e], radii=self.radii[keep_e],
                        signs=self.signs[keep_e], circle_ids=self.circle_ids[keep_e], corners=self.corners[keep_c],
                        corner_obj=self.corner_obj[keep_c], rejected_edges=self.rejected_edges + int(np.sum(~keep_e)),
                        rejected_corners=self.rejected_corners + int(np.sum(~keep_c)))


def view_data(det: Detection, target: Target, origin: tuple[float, float], max_points: int,
              use_corners: bool) -> ViewData:
    """Flatten a detection into refinement observations (edge points subsampled evenly; a view
    with checkerboard corners only has no edge rows)."""
    pts, ctr, rad, sgn, ids = [np.zeros((0, 2))], [np.zeros((0, 2))], [np.zeros(0)], [np.zeros(0, int)], \
        [np.zeros(0, int)]
    for e in det.edges:
        c = target.circles[e.circle]
        p = e.points
        if len(p) > max_points:
            p = p[np.linspace(0, len(p), max_points, endpoint=False).astype(int)]
        pts.append(p)
        ctr.append(np.tile([c.center[0] - origin[0], c.center[1] - origin[1]], (len(p), 1)))
        rad.append(np.full(len(p), c.radius))
        sgn.append(np.full(len(p), 1 if c.dark_inside else -1))
        ids.append(np.full(len(p), e.circle))
    vd = ViewData(np.concatenate(pts), np.concatenate(ctr), np.concatenate(rad), np.concatenate(sgn),
                  np.concatenate(ids))
    if use_corners and det.corners is not None and target.board is not None:
        ok = np.all(np.isfinite(det.corners), 1)  # corners the detector's check rejected are NaN
        vd.corners = det.corners[ok]
        vd.corner_obj = target.board.corner_points()[ok] - np.array(origin)
    return vd
