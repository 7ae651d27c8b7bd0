"""What other commands read back from a calibration's ``report.json`` (written by
:mod:`..report`): the observed field, as the used views' convex hulls and the image size."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import PascalCalibError


class ReportJsonError(PascalCalibError):
    """A report.json that cannot be read; the message names the file and what is wrong."""


def read_view_hulls(path: str | Path) -> tuple[list[np.ndarray], int, int]:
    """(the used views' convex hulls, (K, 2) pixel polygons; image width; image height) from
    ``coverage.view_hulls`` and ``image.width/height``; hulls of fewer than 3 points are left out."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
        hulls = [np.asarray(h, float).reshape(-1, 2) for h in doc["coverage"]["view_hulls"]]
        width, height = int(doc["image"]["width"]), int(doc["image"]["height"])
    except OSError as e:
        raise ReportJsonError(f"{p}: {e.strerror or e}") from None
    except json.JSONDecodeError as e:
        raise ReportJsonError(f"{p}: not a JSON file ({e})") from None
    except (KeyError, TypeError, ValueError) as e:
        raise ReportJsonError(f"{p}: not a calibration report with coverage.view_hulls and image size "
                              f"({e!r})") from None
    hulls = [h for h in hulls if len(h) >= 3 and np.all(np.isfinite(h))]
    if not hulls:
        raise ReportJsonError(f"{p}: the report has no view hulls (no used view)")
    return hulls, width, height
