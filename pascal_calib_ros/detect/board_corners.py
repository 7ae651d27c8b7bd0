"""The corners of a target's board, whatever its kind: a plain checkerboard (:mod:`.checkerboard`,
found whole) or a marker board (:mod:`.marker_boards`: ChArUco, AprilGrid, partial views)."""

from __future__ import annotations

import numpy as np

from ..targets import Target
from .checkerboard import find_checkerboard
from .detection import Detection
from .marker_boards import find_marker_board


def find_board_corners(gray8: np.ndarray, target: Target, det: Detection | None = None) -> np.ndarray | None:
    """(N, 2) corners of the target's board in its corner order, NaN rows for corners not measured,
    or None when the board does not count in this view (``det`` says why)."""
    board = target.board
    if board is None:
        return None
    if board.kind == "checkerboard":
        return find_checkerboard(gray8, target, det)
    return find_marker_board(gray8, board, det)  # type: ignore[arg-type]
