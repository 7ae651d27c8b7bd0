"""mrcal ``.cameramodel`` files (http://mrcal.secretsauce.net/cameramodels.html).

The format is the text of a Python dict (mrcal reads it with ``ast.literal_eval``; so does this
module, which never evaluates code)::

    {
        'lensmodel':  'LENSMODEL_OPENCV8',
        # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....
        'intrinsics': [ fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 ],
        'rt_cam_ref': [ rx, ry, rz, tx, ty, tz ],     # the camera's pose: reference -> camera
        'extrinsics': [ ... ],                        # the same, for mrcal < 2.5
        'imagersize': [ width, height ],
    }

Lens models (mrcal's ``lensmodels`` page): ``LENSMODEL_PINHOLE`` (no distortion),
``LENSMODEL_OPENCV4`` (k1 k2 p1 p2), ``LENSMODEL_OPENCV5`` (+ k3), ``LENSMODEL_OPENCV8``
(+ k4 k5 k6) and ``LENSMODEL_OPENCV12`` (+ thin prism s1..s4) are OpenCV's formulas with OpenCV's
coefficient order, so plumb_bob is written as OPENCV5 and rational_polynomial as OPENCV8, exactly.
mrcal has no equidistant (fisheye) model: a fisheye is refitted into one mrcal has
(:mod:`~..analysis.refit`, ``LENSMODEL_SPLINED_STEREOGRAPHIC_...`` of :mod:`.mrcal_splined`).
Numbers are written with ``repr`` (17 significant digits; mrcal's own writer keeps 10), so a
model read back projects as ours to the last bits. mrcal has no skew.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry import Camera, ImageSize
from .format_error import CalibrationFileError, check_exportable
from .mrcal_splined import SplinedModel, parse_lensmodel, splined_camera

# mrcal lens model -> (our model, number of distortion coefficients mrcal stores)
OPENCV_MODELS = {"LENSMODEL_PINHOLE": ("plumb_bob", 0), "LENSMODEL_OPENCV4": ("plumb_bob", 4),
                 "LENSMODEL_OPENCV5": ("plumb_bob", 5), "LENSMODEL_OPENCV8": ("rational_polynomial", 8),
                 "LENSMODEL_OPENCV12": ("rational_polynomial", 12)}
WRITTEN_AS = {"plumb_bob": "LENSMODEL_OPENCV5", "rational_polynomial": "LENSMODEL_OPENCV8"}


@dataclass(frozen=True)
class MrcalModel:
    """The fields of a ``.cameramodel`` this package reads and writes."""

    lensmodel: str
    intrinsics: np.ndarray  # fx fy cx cy, then the model's parameters
    width: int
    height: int
    rt_cam_ref: np.ndarray = field(default_factory=lambda: np.zeros(6))
    valid_intrinsics_region: np.ndarray | None = None  # closed contour (N, 2), first == last

    @property
    def size(self) -> ImageSize:
        """The image size (width, height)."""
        return ImageSize(self.width, self.height)


def looks_like_mrcal(text: str) -> bool:
    """Whether a file's text is a ``.cameramodel`` dict (comments, then '{' and a 'lensmodel' key)."""
    body = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#")).lstrip()
    return body.startswith("{") and "'lensmodel'" in body[:2000]


def mrcal_model_of_camera(camera: Camera) -> MrcalModel:
    """The exact mrcal model of a plumb_bob or rational_polynomial camera; an equidistant one
    raises :class:`CalibrationFileError` naming the refit."""
    check_exportable(camera, "mrcal")
    if camera.model not in WRITTEN_AS:
        raise CalibrationFileError(f"mrcal has no {camera.model} model: export it with a refit (pascal-calib export "
                                   "--to mrcal refits a fisheye into LENSMODEL_SPLINED_STEREOGRAPHIC and states the "
                                   "error)")
    K = camera.K
    intr = np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.asarray(camera.D, float)]
    return MrcalModel(WRITTEN_AS[camera.model], intr, int(camera.width), int(camera.height))


def camera_of_mrcal_model(model: MrcalModel, where: str = "cameramodel") -> Camera:
    """Our camera of an mrcal OPENCV* or PINHOLE model, or a
    :class:`~.mrcal_splined.SplinedCamera` of a cubic splined stereographic one (which ``diff`` and
    ``export --model`` take; others: :class:`CalibrationFileError`)."""
    spline = parse_lensmodel(model.lensmodel)
    if spline is not None:
        order, nx, ny, fov = spline
        if order != 3:
            raise CalibrationFileError(f"{where}: splined models of order {order}: only cubic (order 3) ones read")
        try:
            return splined_camera(SplinedModel(nx, ny, fov, np.asarray(model.intrinsics, float), model.width,
                                               model.height))
        except ValueError as e:
            raise CalibrationFileError(f"{where}: {e}") from None
    if model.lensmodel not in OPENCV_MODELS:
        raise CalibrationFileError(f"{where}: lens model {model.lensmodel} has no equivalent here (readable: "
                                   f"{', '.join(OPENCV_MODELS)})")
    name, n = OPENCV_MODELS[model.lensmodel]
    intr = np.asarray(model.intrinsics, float)
    if len(intr) != 4 + n:
        raise CalibrationFileError(f"{where}: {model.lensmodel} has {4 + n} intrinsics, got {len(intr)}")
    D = intr[4:]
    if n == 12:
        if np.any(D[8:] != 0):
            raise CalibrationFileError(f"{where}: LENSMODEL_OPENCV12 with non-zero thin-prism terms "
                                       f"{D[8:].tolist()}: no equivalent here")
        D = D[:8]
    D = np.r_[D, np.zeros(5 - len(D))] if len(D) < 5 else D
    fx, fy, cx, cy = intr[:4]
    return Camera.from_params(float(fx), float(fy), float(cx), float(cy), dist=D, width=model.width,
                              height=model.height, model=name)


def _numbers(values: np.ndarray) -> str:
    return "[ " + " ".join(f"{float(v)!r}," for v in np.asarray(values, float).ravel()) + " ]"


def mrcal_model_text(model: MrcalModel, note: str = "") -> str:
    """The ``.cameramodel`` text (module docstring)."""
    lines = [f"# {line}" for line in note.splitlines()]
    lines += ["{", f"    'lensmodel':  '{model.lensmodel}',", "",
              "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....",
              f"    'intrinsics': {_numbers(model.intrinsics)},", ""]
    if model.valid_intrinsics_region is not None and len(model.valid_intrinsics_region):
        lines.append("    'valid_intrinsics_region': [")
        lines += [f"    [ {float(u)!r}, {float(v)!r} ]," for u, v in model.valid_intrinsics_region]
        lines += ["    ],", ""]
    lines += [f"    'rt_cam_ref': {_numbers(model.rt_cam_ref)},",
              f"    'extrinsics': {_numbers(model.rt_cam_ref)},  # for compatibility with mrcal < 2.5", "",
              f"    'imagersize': [ {int(model.width)}, {int(model.height)} ],", "}", ""]
    return "\n".join(lines)


def write_mrcal_model(path: str | Path, model: MrcalModel, note: str = "") -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(mrcal_model_text(model, note))
    return p


def parse_mrcal_model(text: str, where: str = "cameramodel") -> MrcalModel:
    """The model of a ``.cameramodel`` text (``ast.literal_eval``: literals only, no code)."""
    try:
        doc = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as e:
        raise CalibrationFileError(f"{where}: not an mrcal .cameramodel ({type(e).__name__})") from None
    if not isinstance(doc, dict):
        raise CalibrationFileError(f"{where}: not an mrcal .cameramodel (not a dict)")
    name = doc.get("lensmodel", doc.get("lens_model", doc.get("distortion_model")))
    if not isinstance(name, str) or "intrinsics" not in doc or "imagersize" not in doc:
        raise CalibrationFileError(f"{where}: an mrcal .cameramodel needs lensmodel, intrinsics and imagersize")
    try:
        intr = np.asarray(doc["intrinsics"], float).ravel()
        size = np.asarray(doc["imagersize"], float).ravel()
        rt = np.asarray(doc.get("rt_cam_ref", doc.get("extrinsics", np.zeros(6))), float).ravel()
        region = doc.get("valid_intrinsics_region")
        region_a = None if region is None else np.asarray(region, float).reshape(-1, 2)
    except (TypeError, ValueError) as e:
        raise CalibrationFileError(f"{where}: malformed field ({e})") from None
    if size.size != 2 or np.any(size <= 0) or np.any(size != np.round(size)):
        raise CalibrationFileError(f"{where}: imagersize must be two positive integers, got {doc['imagersize']!r}")
    if rt.size != 6 or not np.all(np.isfinite(intr)) or not np.all(np.isfinite(rt)):
        raise CalibrationFileError(f"{where}: rt_cam_ref must be 6 numbers and the intrinsics finite")
    return MrcalModel(name.replace("DISTORTION", "LENSMODEL"), intr, int(size[0]), int(size[1]), rt, region_a)


def read_mrcal_model(path: str | Path) -> MrcalModel:
    p = Path(path)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"{p}: cannot read ({e})") from None
    return parse_mrcal_model(text, str(p))
