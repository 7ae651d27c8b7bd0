"""``pascal-calib export``: a calibration in another consumer's format, refitted where the format
cannot hold the model (:mod:`~..analysis.refit`), with the refit's error stated.

Formats (``to``) and what each holds exactly:

============  =====================================================  ==============================
to            writes                                                 refits (error stated)
============  =====================================================  ==============================
opencv        FileStorage YAML (:mod:`~..io.opencv_storage`)          only with ``model``
kalibr        camchain entry (:mod:`~..io.kalibr_camchain`): radtan   plumb_bob with k3 != 0 and
              (plumb_bob with k3 = 0) or equidistant                  rational_polynomial -> radtan
mrcal         ``.cameramodel`` (:mod:`~..io.mrcal_model`):            equidistant -> SPLINED_STEREO-
              OPENCV5 / OPENCV8                                       GRAPHIC (:mod:`~..analysis.refit_splined`)
json          ``calibration.json`` (:mod:`~..io.calibration_json`)   only with ``model``
urdf          a fixed joint of a HAND_EYE.yaml                        -
static_transform  the static_transform_publisher command of one       -
============  =====================================================  ==============================

``model`` (``plumb_bob``, ``none`` = a pinhole, or any ``--distortion`` choice) asks for a refit
into that model whatever the format; for Kalibr ``plumb_bob`` means radtan (k3 = 0). A camera with
skew is refitted without it for opencv, kalibr and mrcal (none has a skew term). The refit is over
``region`` (a ``report.json`` or ``calibration.json``: its observed field) or the whole image, and
is refused above ``max_error_px`` unless ``force``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from ..analysis import CHOICE as SPLINED
from ..analysis import DEFAULT_MAX_ERROR_PX, CompareError, RefitResult, refit_camera, refit_splined, region_from_report
from ..errors import PascalCalibError
from ..geometry import DISTORTION_CHOICES, Camera
from ..io import (
    CalibrationFile,
    CalibrationFileError,
    CalibrationRecord,
    KalibrCamera,
    MrcalModel,
    PosesYamlError,
    SplinedCamera,
    kalibr_distortion,
    mrcal_model_of_camera,
    read_calibration_file,
    read_hand_eye_yaml,
    static_transform_text,
    urdf_joint_text,
    write_calibration_json,
    write_kalibr_camchain,
    write_mrcal_model,
    write_opencv_storage,
)

CAMERA_FORMATS = ("opencv", "kalibr", "mrcal", "json")
HAND_EYE_FORMATS = ("urdf", "static_transform")
FORMATS = CAMERA_FORMATS + HAND_EYE_FORMATS


class ExportError(PascalCalibError):
    """The export cannot be done as asked (bad input, a model the format cannot hold)."""


@dataclass(frozen=True)
class ExportRequest:
    source: Path
    to: str
    output: Path
    model: str = ""  # refit into this DISTORTION_CHOICES key ("": only where the format needs it)
    region: Path | None = None  # report.json / calibration.json whose observed field the refit is fitted over
    force: bool = False
    max_error_px: float = DEFAULT_MAX_ERROR_PX
    camera: str = ""  # the entry of a multi-camera source (Kalibr cam0, cam1, ...)
    rostopic: str = ""  # Kalibr: the camera's image topic


@dataclass
class ExportOutcome:
    path: Path
    refit: RefitResult | None = None
    lines: list[str] = field(default_factory=list)


def refit_choice(camera: Camera, to: str, model: str) -> str:
    """The DISTORTION_CHOICES key to refit into ("" for none) for writing ``camera`` to ``to``."""
    if model:
        if model not in DISTORTION_CHOICES:
            raise ExportError(f"unknown model {model!r}; choose one of {', '.join(DISTORTION_CHOICES)}")
        if to == "kalibr" and DISTORTION_CHOICES[model][0].name == "plumb_bob" and model != "none":
            return "plumb_bob_k3_fixed" if model in ("plumb_bob", "plumb_bob_k3_fixed") else model
        if (to == "kalibr" and model == "rational_polynomial") or (to == "mrcal" and model == "equidistant"):
            raise ExportError(f"{to} has no {model} model")
        return model
    if isinstance(camera, SplinedCamera):
        if to == "mrcal":
            return ""
        raise ExportError(f"an mrcal splined model has no {to} equivalent: name the model to refit it into "
                          "(--model plumb_bob, rational_polynomial, ...)")
    skew = camera.K[0, 1] != 0.0 and to != "json"
    if to == "kalibr":
        try:
            kalibr_distortion(camera)
        except CalibrationFileError:
            return "plumb_bob_k3_fixed"
        return camera.model if skew else ""
    if to == "mrcal" and camera.model == "equidistant":
        return SPLINED
    return camera.model if skew else ""


def _region(req: ExportRequest, cf: CalibrationFile) -> tuple[np.ndarray | None, str, list[np.ndarray]]:
    if req.region is None:
        return None, "the whole image", []
    try:
        reg = region_from_report(req.region)
    except CompareError as e:
        raise ExportError(str(e)) from None
    cam = cf.camera
    if (reg.width, reg.height) != (cam.width, cam.height):
        raise ExportError(f"{req.region}: the region is of {reg.width}x{reg.height} images, the camera "
                          f"{cam.width}x{cam.height}")
    return reg.mask, f"the observed field of {req.region.name}", reg.hulls


def region_contour(mask: np.ndarray) -> np.ndarray:
    """The outer contour (N, 2), closed (first == last), of a region's largest part: mrcal's
    ``valid_intrinsics_region``."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    c = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(float)
    return np.vstack([c, c[:1]])


def _write(req: ExportRequest, cf: CalibrationFile, cam: Camera, note: str, mask: np.ndarray | None,
           hulls: list[np.ndarray], refitted: str) -> Path:
    """Write ``cam`` in ``req.to``; ``refitted``: the choice it was refitted into ("" if not)."""
    if req.to == "opencv":
        return write_opencv_storage(req.output, cam, note)
    if req.to == "kalibr":
        return write_kalibr_camchain(req.output, [KalibrCamera(cam, rostopic=req.rostopic)], note)
    if req.to == "mrcal":
        if isinstance(cam, SplinedCamera) and cam.spline is not None:
            sp = cam.spline
            model = MrcalModel(sp.lensmodel, sp.intrinsics, sp.width, sp.height)
        else:
            model = mrcal_model_of_camera(cam)
        if mask is not None and mask.any():
            model = replace(model, valid_intrinsics_region=region_contour(mask))
        return write_mrcal_model(req.output, model, note)
    rec = cf.record
    if refitted:  # the covariance was of the source's parameters, not the refit's
        rec = CalibrationRecord(cam, rec.camera_name, distortion_choice=refitted if refitted in DISTORTION_CHOICES
                                else "", view_hulls=hulls or rec.view_hulls, note=note)
    elif hulls and not rec.view_hulls:
        rec = replace(rec, view_hulls=hulls)
    return write_calibration_json(req.output, replace(rec, note=note or rec.note))


def _export_hand_eye(req: ExportRequest) -> ExportOutcome:
    try:
        doc, X = read_hand_eye_yaml(req.source)
    except PosesYamlError as e:
        raise ExportError(f"{e} (--to {req.to} exports a HAND_EYE.yaml)") from None
    text = urdf_joint_text(doc, X) if req.to == "urdf" else static_transform_text(doc, X)
    req.output.parent.mkdir(parents=True, exist_ok=True)
    req.output.write_text(text)
    return ExportOutcome(req.output, None, [text.rstrip(), f"wrote {req.output}"])


def export_calibration(req: ExportRequest) -> ExportOutcome:
    """Export as asked (module docstring). Raises :class:`ExportError` /
    :class:`~..io.format_error.CalibrationFileError` for bad input and
    :class:`~..analysis.refit.RefitError` for a refit refused."""
    if req.to not in FORMATS:
        raise ExportError(f"unknown format {req.to!r}; choose one of {', '.join(FORMATS)}")
    if req.to in HAND_EYE_FORMATS:
        if req.model or req.region:
            raise ExportError(f"--model and --region apply to camera exports, not --to {req.to}")
        return _export_hand_eye(req)
    if not (np.isfinite(req.max_error_px) and req.max_error_px > 0):
        raise ExportError(f"--max-error must be a positive number of pixels, got {req.max_error_px}")
    cf = read_calibration_file(req.source, req.camera)
    lines = [f"read {req.source} ({cf.format}{', ' + ', '.join(cf.notes) if cf.notes else ''}): {cf.camera.model}, "
             f"{cf.camera.width}x{cf.camera.height}"]
    mask, where, hulls = _region(req, cf)
    choice = refit_choice(cf.camera, req.to, req.model)
    refit = None
    cam = cf.camera
    note = f"exported by pascal-calib from {req.source.name} ({cf.format})"
    if choice:
        refit = (refit_splined(cf.camera, mask, where, req.max_error_px, req.force) if choice == SPLINED
                 else refit_camera(cf.camera, choice, mask, where, req.max_error_px, req.force))
        cam = refit.camera
        lines.append(refit.summary())
        if not refit.ok:
            lines.append(f"WARNING (forced): {refit.where_it_fails()}")
        note += f"\n{refit.summary()}"
    path = _write(req, cf, cam, note, mask, hulls, choice)
    lines.append(f"wrote {path} ({req.to}, {cam.model})")
    return ExportOutcome(path, refit, lines)
