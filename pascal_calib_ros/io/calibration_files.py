"""Read any supported calibration file by its content: a :class:`~..geometry.camera.Camera` and
what else the file carries.

Recognised (the content decides, not the file name), in this order:

- ``json``: this package's ``calibration.json`` (:mod:`.calibration_json`; with the covariance
  and the observed field);
- ``opencv``: an OpenCV FileStorage file (:mod:`.opencv_storage`; ``%YAML:1.0`` header,
  ``!!opencv-matrix`` tags, or XML);
- ``mrcal``: an mrcal ``.cameramodel`` (:mod:`.mrcal_model`);
- ``kalibr``: a Kalibr camchain (:mod:`.kalibr_camchain`; ``camera`` picks the entry, default cam0);
- ``ros``: a ``camera_calibration_parsers`` YAML (:mod:`.camera_yaml`); its ``.calibration.json``
  sidecar, when one lies beside it and holds the same camera, is attached as the record.

A HAND_EYE.yaml is refused with what to do with it (``pascal-calib export --to urdf``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from ..geometry import Camera, Transform
from .calibration_json import CalibrationRecord, looks_like_calibration_json, record_of_document, sidecar_path
from .camera_yaml import CameraYamlError, read_camera_yaml
from .format_error import CalibrationFileError
from .kalibr_camchain import KalibrCamera, kalibr_cameras, looks_like_kalibr
from .mrcal_model import MrcalModel, camera_of_mrcal_model, looks_like_mrcal, parse_mrcal_model
from .opencv_storage import camera_from_opencv_text, looks_like_opencv_storage

FORMATS = ("json", "opencv", "mrcal", "kalibr", "ros")


@dataclass(frozen=True)
class CalibrationFile:
    """A calibration file read: its format, the calibrated camera (one :class:`CalibrationRecord`
    whatever the format: a format without a covariance or an observed field leaves them unknown),
    and the format's extras."""

    path: Path
    format: str  # one of FORMATS
    record: CalibrationRecord
    kalibr: tuple[KalibrCamera, ...] = ()  # every camera of a camchain
    mrcal: MrcalModel | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def camera(self) -> Camera:
        return self.record.camera

    @property
    def camera_name(self) -> str:
        return self.record.camera_name

    @property
    def T_cn_cnm1(self) -> Transform | None:
        """The chosen camchain entry's transform from the previous camera (Kalibr rigs)."""
        for k in self.kalibr:
            if k.name == self.camera_name:
                return k.T_cn_cnm1
        return None


def same_camera(a: Camera, b: Camera, rel: float = 1e-9) -> bool:
    """Whether two cameras are one (size, model, K and D equal to ``rel``)."""
    if (a.width, a.height, a.model) != (b.width, b.height, b.model) or len(a.D) != len(b.D):
        return False
    scale = max(float(np.abs(a.K).max()), 1.0)
    return bool(np.allclose(a.K, b.K, rtol=0, atol=rel * scale) and np.allclose(a.D, b.D, rtol=rel, atol=rel))


def _ros(p: Path) -> CalibrationFile:
    try:
        info = read_camera_yaml(p)
        cam = Camera(info.K, info.D, info.width, info.height, info.distortion_model)
        bare = CalibrationRecord(cam, info.camera_name or "camera")
    except (CameraYamlError, ValueError) as e:
        raise CalibrationFileError(f"{p}: not a calibration file this package reads (json, OpenCV FileStorage, "
                                   f"mrcal .cameramodel, Kalibr camchain, ROS camera YAML): {e}") from None
    side = sidecar_path(p)
    if not side.exists():
        return CalibrationFile(p, "ros", bare)
    try:
        rec = record_of_document(json.loads(side.read_text()), str(side))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, CalibrationFileError) as e:
        return CalibrationFile(p, "ros", bare, notes=(f"{side.name} ignored: {e}",))
    if not same_camera(rec.camera, bare.camera):
        return CalibrationFile(p, "ros", bare,
                               notes=(f"{side.name} ignored: it holds another camera than {p.name}",))
    return CalibrationFile(p, "ros", replace(rec, camera=bare.camera), notes=(f"with {side.name}",))


def _yaml_formats(p: Path, text: str, camera: str) -> CalibrationFile | None:
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError:
        return None
    if looks_like_kalibr(doc):
        cams = kalibr_cameras(doc, str(p))
        name = camera or "cam0"
        chosen = [k for k in cams if k.name == name]
        if not chosen:
            raise CalibrationFileError(f"{p}: no camera {name!r} (it has {', '.join(k.name for k in cams)})")
        notes = (f"camera {name} of {len(cams)}",) if len(cams) > 1 else ()
        return CalibrationFile(p, "kalibr", CalibrationRecord(chosen[0].camera, name), kalibr=tuple(cams), notes=notes)
    if isinstance(doc, dict) and "translation" in doc and "rotation" in doc and "camera_matrix" not in doc:
        raise CalibrationFileError(f"{p}: a hand-eye result, not a camera calibration (export it with "
                                   "pascal-calib export --to urdf or --to static_transform)")
    return None


def read_calibration_file(path: str | Path, camera: str = "") -> CalibrationFile:
    """Read ``path`` in whichever supported format its content is (module docstring); ``camera``
    names the entry of a multi-camera file (Kalibr: cam0, cam1, ...)."""
    p = Path(path)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"{p}: cannot read ({getattr(e, 'strerror', None) or e})") from None
    if text.lstrip().startswith("{"):
        try:
            doc = json.loads(text)
        except json.JSONDecodeError:
            doc = None
        if looks_like_calibration_json(doc):
            rec = record_of_document(doc, str(p))
            return CalibrationFile(p, "json", rec)
    if looks_like_opencv_storage(text):
        return CalibrationFile(p, "opencv", CalibrationRecord(camera_from_opencv_text(text, str(p))))
    if looks_like_mrcal(text):
        model = parse_mrcal_model(text, str(p))
        return CalibrationFile(p, "mrcal", CalibrationRecord(camera_of_mrcal_model(model, str(p))), mrcal=model)
    found = _yaml_formats(p, text, camera)
    if found is not None:
        return found
    return _ros(p)
