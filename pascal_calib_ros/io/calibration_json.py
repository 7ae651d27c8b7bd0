"""``calibration.json``: a camera with what a later check of it needs (this package's own format).

Written beside the camera YAML by ``pascal-calib calibrate`` and ``handeye`` (``CAM.calibration.json``
for ``-o CAM.yaml``) and by ``pascal-calib export --to json``. The YAML alone cannot say how well
the calibration is known; ``pascal-calib verify`` tests fresh views against this covariance, and
``export --region`` refits over this observed field. Keys::

    format: "pascal_calib_ros.calibration", version: 1
    camera_name, created (UTC, ISO 8601)
    image: {width, height}
    camera_matrix: 3x3, distortion_model: plumb_bob | rational_polynomial | equidistant,
    distortion_coefficients: [...]          (ROS / OpenCV order)
    estimated: {distortion_choice: what was estimated (a --distortion choice),
                parameters: names of the estimated intrinsics (fx fy cx cy [skew] k1 ...),
                std: {name: sigma}, covariance: their covariance (rows and columns in that order;
                the refinement's sandwich covariance with the views' poses marginalised)}
    coverage: {view_hulls: [[[u, v], ...], ...]}   (the observed field, as report.json)
    rms_px, views_used, projection_uncertainty: {median_px, worst_px, distance_m}
    note: free text (e.g. what a refit did and its error)

Absent or null fields are simply unknown (a file exported from another tool's calibration has no
covariance).
"""

from __future__ import annotations

import datetime
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry import Camera
from .atomic import write_text_atomic
from .format_error import CalibrationFileError

FORMAT = "pascal_calib_ros.calibration"
VERSION = 1
SUFFIX = ".calibration.json"


@dataclass(frozen=True)
class CalibrationRecord:
    """A camera and, where known, how it was estimated (module docstring)."""

    camera: Camera
    camera_name: str = "camera"
    distortion_choice: str = ""
    parameters: tuple[str, ...] = ()
    covariance: np.ndarray | None = None  # (P, P) over ``parameters``
    view_hulls: list[np.ndarray] = field(default_factory=list)
    rms_px: float = float("nan")
    views_used: int = 0
    projection_uncertainty: dict[str, float] | None = None
    created: str = ""
    note: str = ""

    @property
    def choice(self) -> str:
        """The ``--distortion`` choice it was estimated with (its model's full set when not recorded)."""
        return self.distortion_choice or self.camera.model

    @property
    def std(self) -> dict[str, float]:
        if self.covariance is None:
            return {}
        return {n: float(np.sqrt(max(self.covariance[i, i], 0.0))) for i, n in enumerate(self.parameters)}


def sidecar_path(camera_yaml: str | Path) -> Path:
    """``CAM.calibration.json`` beside ``CAM.yaml``."""
    p = Path(camera_yaml)
    return p.with_name(p.stem + SUFFIX) if p.suffix else p.with_name(p.name + SUFFIX)


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def record_document(rec: CalibrationRecord) -> dict[str, Any]:
    c = rec.camera
    est: dict[str, Any] = {"distortion_choice": rec.distortion_choice or None, "parameters": list(rec.parameters),
                           "std": rec.std or None,
                           "covariance": None if rec.covariance is None else np.asarray(rec.covariance).tolist()}
    return {
        "format": FORMAT, "version": VERSION, "camera_name": rec.camera_name,
        "created": rec.created or datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "image": {"width": int(c.width), "height": int(c.height)},
        "camera_matrix": np.asarray(c.K, float).tolist(), "distortion_model": c.model,
        "distortion_coefficients": np.asarray(c.D, float).tolist(),
        "estimated": est,
        "coverage": {"view_hulls": [np.round(np.asarray(h, float), 2).tolist() for h in rec.view_hulls]},
        "rms_px": _finite_or_none(rec.rms_px), "views_used": int(rec.views_used),
        "projection_uncertainty": rec.projection_uncertainty, "note": rec.note,
    }


def calibration_json_text(rec: CalibrationRecord) -> str:
    return json.dumps(record_document(rec), indent=1, allow_nan=False) + "\n"


def write_calibration_json(path: str | Path, rec: CalibrationRecord) -> Path:
    """Write atomically (:mod:`.atomic`)."""
    return write_text_atomic(path, calibration_json_text(rec))


def looks_like_calibration_json(doc: object) -> bool:
    return isinstance(doc, dict) and doc.get("format") == FORMAT


def _covariance(est: dict[str, Any], where: str) -> tuple[tuple[str, ...], np.ndarray | None]:
    names = tuple(str(n) for n in (est.get("parameters") or ()))
    cov = est.get("covariance")
    if cov is None:
        return names, None
    C = np.asarray(cov, float)
    if C.shape != (len(names), len(names)) or not np.all(np.isfinite(C)):
        raise CalibrationFileError(f"{where}: estimated.covariance must be a finite {len(names)}x{len(names)} "
                                   "matrix over estimated.parameters")
    return names, C


def record_of_document(doc: object, where: str = "calibration.json") -> CalibrationRecord:
    if not looks_like_calibration_json(doc):
        raise CalibrationFileError(f"{where}: not a {FORMAT} file")
    assert isinstance(doc, dict)
    if int(doc.get("version", 0)) > VERSION:
        raise CalibrationFileError(f"{where}: version {doc.get('version')} is newer than this reader ({VERSION})")
    try:
        img = doc["image"]
        K = np.asarray(doc["camera_matrix"], float)
        cam = Camera(K, np.asarray(doc["distortion_coefficients"], float), int(img["width"]), int(img["height"]),
                     str(doc["distortion_model"]))
        est = doc.get("estimated") or {}
        names, cov = _covariance(est, where)
        hulls = [np.asarray(h, float).reshape(-1, 2) for h in (doc.get("coverage") or {}).get("view_hulls") or []]
        rms = doc.get("rms_px")
        return CalibrationRecord(camera=cam, camera_name=str(doc.get("camera_name", "camera")),
                                 distortion_choice=str(est.get("distortion_choice") or ""), parameters=names,
                                 covariance=cov, view_hulls=hulls,
                                 rms_px=float(rms) if rms is not None else float("nan"),
                                 views_used=int(doc.get("views_used") or 0),
                                 projection_uncertainty=doc.get("projection_uncertainty"),
                                 created=str(doc.get("created", "")), note=str(doc.get("note", "")))
    except CalibrationFileError:
        raise
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationFileError(f"{where}: missing or malformed field ({e!r})") from None


def read_calibration_json(path: str | Path) -> CalibrationRecord:
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CalibrationFileError(f"{p}: cannot read ({e})") from None
    return record_of_document(doc, str(p))
