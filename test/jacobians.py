"""Central differences for the tests that check an analytic Jacobian."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def numeric_jacobian(residuals: Callable[[np.ndarray], np.ndarray], x: np.ndarray, rel: float, floor: float
                     ) -> np.ndarray:
    """d residuals / d x by central differences, each step ``rel`` x max(|x_j|, ``floor``)."""
    cols = []
    for j in range(len(x)):
        h = rel * max(abs(x[j]), floor)
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        cols.append((residuals(xp) - residuals(xm)) / (2 * h))
    return np.stack(cols, 1)
