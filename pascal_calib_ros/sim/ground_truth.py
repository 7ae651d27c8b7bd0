"""Accuracy of a calibration against a rendered session's ground truth (``session.json`` of
``pascal-calib render``), for the demo (``tools/demo.py``) and the tests."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry import Camera, calibration_errors


def errors_against_truth(truth: dict[str, Any], K: np.ndarray, D: np.ndarray, model: str = "") -> dict[str, float]:
    """Errors of (K, D) of lens ``model`` (default: inferred from len(D)) against a rendered
    session's ground truth (session.json contents)."""
    cam_t = Camera(np.array(truth["K"]), np.array(truth["D"]), truth["width"], truth["height"],
                   truth.get("distortion_model", "plumb_bob"))
    return calibration_errors(cam_t, K, D, model)


def compare(truth_json: Path, calib_yaml: Path) -> dict[str, float]:
    """Errors of a calibration file (any format :func:`~..io.read_calibration_file` reads) against a
    rendered session's ground truth."""
    from ..io import read_calibration_file

    cam = read_calibration_file(calib_yaml).camera
    return errors_against_truth(json.loads(truth_json.read_text()), cam.K, cam.D, cam.model)
