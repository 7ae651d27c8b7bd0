"""Kalibr camchain YAML (https://github.com/ethz-asl/kalibr/wiki/yaml-formats).

One entry per camera, ``cam0``, ``cam1``, ...::

    cam0:
      camera_model: pinhole              # Kalibr also has omni, ds, eucm: no equivalent here
      intrinsics: [fu, fv, pu, pv]       # fx fy cx cy
      distortion_model: radtan           # radtan (k1 k2 r1 r2) | equidistant (k1 k2 k3 k4) | none
      distortion_coeffs: [k1, k2, r1, r2]
      resolution: [width, height]
      rostopic: /cam0/image_raw
    cam1:
      ...
      T_cn_cnm1: 4x4 rows                # takes cam0 coordinates into cam1's (p_c1 = T p_c0)

Model mapping: ``radtan`` is plumb_bob without k3 (Kalibr's RadialTangentialDistortion: k1 k2 and
the tangential r1 r2 = p1 p2, OpenCV's formulas); ``equidistant`` is OpenCV's fisheye model
(Kannala-Brandt k1..k4), ours exactly; ``none`` is plumb_bob with zeros. A plumb_bob camera with
k3 != 0 or a rational_polynomial one has no radtan equivalent: writing it raises
:class:`CalibrationFileError` naming the refit (``pascal-calib export --to kalibr`` does that
refit, plumb_bob with k3 = 0 over the observed field, and states its error). Kalibr has no skew.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..geometry import Camera, Transform, TransformError
from .format_error import CalibrationFileError, check_exportable


@dataclass(frozen=True)
class KalibrCamera:
    """One camchain entry: the camera, its transform from the previous camera (None for cam0)
    and its image topic."""

    camera: Camera
    T_cn_cnm1: Transform | None = None
    rostopic: str = ""
    name: str = "cam0"


def kalibr_distortion(camera: Camera) -> tuple[str, list[float]]:
    """(distortion_model, distortion_coeffs) of a camera, or :class:`CalibrationFileError` if
    Kalibr's models cannot hold it exactly."""
    D = np.asarray(camera.D, float)
    if camera.model == "equidistant":
        return "equidistant", [float(v) for v in D]
    if camera.model == "plumb_bob" and D[4] == 0.0:
        return "radtan", [float(v) for v in D[:4]]
    if camera.model == "rational_polynomial" and not np.any(D[4:]):
        return "radtan", [float(v) for v in D[:4]]
    why = "k3 != 0" if camera.model == "plumb_bob" else "a rational radial factor"
    raise CalibrationFileError(f"Kalibr's radtan model has k1 k2 p1 p2 only; this {camera.model} camera has {why}: "
                               "export it with a refit (pascal-calib export --to kalibr refits plumb_bob with k3 = 0 "
                               "and states the error)")


def _entry(cam: KalibrCamera) -> dict[str, Any]:
    c = cam.camera
    check_exportable(c, "Kalibr")
    model, coeffs = kalibr_distortion(c)
    K = c.K
    out: dict[str, Any] = {"camera_model": "pinhole",
                           "intrinsics": [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])],
                           "distortion_model": model, "distortion_coeffs": coeffs,
                           "resolution": [int(c.width), int(c.height)]}
    if cam.rostopic:
        out["rostopic"] = cam.rostopic
    if cam.T_cn_cnm1 is not None:
        out["T_cn_cnm1"] = [[float(v) for v in row] for row in cam.T_cn_cnm1.matrix]
    return out


def kalibr_camchain_text(cameras: list[KalibrCamera], note: str = "") -> str:
    """The camchain YAML of one or more cameras (cam0 first; every later one with its T_cn_cnm1)."""
    if not cameras:
        raise CalibrationFileError("no camera to write")
    doc = {f"cam{i}": _entry(c) for i, c in enumerate(cameras)}
    head = "".join(f"# {line}\n" for line in note.splitlines())
    return head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def write_kalibr_camchain(path: str | Path, cameras: list[KalibrCamera], note: str = "") -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(kalibr_camchain_text(cameras, note))
    return p


def looks_like_kalibr(doc: object) -> bool:
    """Whether a loaded YAML document is a camchain: cam0 with intrinsics."""
    return isinstance(doc, dict) and isinstance(doc.get("cam0"), dict) and "intrinsics" in doc["cam0"]


def _numbers(v: Any, n: int | None, what: str) -> np.ndarray:
    try:
        a = np.asarray(v, float).ravel()
    except (TypeError, ValueError):
        raise CalibrationFileError(f"{what}: expected numbers, got {v!r}") from None
    if (n is not None and a.size != n) or not np.all(np.isfinite(a)):
        raise CalibrationFileError(f"{what}: expected {n if n is not None else 'some'} finite numbers, got {v!r}")
    return a


def _camera(entry: dict[str, Any], where: str) -> Camera:
    kind = entry.get("camera_model", "pinhole")
    if kind != "pinhole":
        raise CalibrationFileError(f"{where}: camera_model {kind!r} has no equivalent here (pinhole only; Kalibr's "
                                   "omni, ds and eucm models project differently)")
    fx, fy, cx, cy = _numbers(entry.get("intrinsics"), 4, f"{where}: intrinsics [fu fv pu pv]")
    res = _numbers(entry.get("resolution"), 2, f"{where}: resolution [width height]")
    model = entry.get("distortion_model", "none")
    coeffs = entry.get("distortion_coeffs", [])
    if model == "radtan":
        D, name = np.r_[_numbers(coeffs, 4, f"{where}: radtan distortion_coeffs"), 0.0], "plumb_bob"
    elif model == "equidistant":
        D, name = _numbers(coeffs, 4, f"{where}: equidistant distortion_coeffs"), "equidistant"
    elif model == "none":
        D, name = np.zeros(5), "plumb_bob"
    else:
        raise CalibrationFileError(f"{where}: distortion_model {model!r} has no equivalent here (radtan, "
                                   "equidistant, none)")
    return Camera.from_params(float(fx), float(fy), float(cx), float(cy), dist=D, width=int(res[0]),
                              height=int(res[1]), model=name)


def kalibr_cameras(doc: object, where: str = "camchain") -> list[KalibrCamera]:
    """Every camera of a loaded camchain document, cam0 first."""
    if not looks_like_kalibr(doc):
        raise CalibrationFileError(f"{where}: not a Kalibr camchain (no cam0 with intrinsics)")
    assert isinstance(doc, dict)
    out = []
    i = 0
    while f"cam{i}" in doc:
        name = f"cam{i}"
        entry = doc[name]
        if not isinstance(entry, dict):
            raise CalibrationFileError(f"{where}: {name} is not a mapping")
        T = None
        if "T_cn_cnm1" in entry:
            try:
                T = Transform.from_matrix(_numbers(entry["T_cn_cnm1"], 16, f"{where}: {name}.T_cn_cnm1").reshape(4, 4))
            except TransformError as e:
                raise CalibrationFileError(f"{where}: {name}.T_cn_cnm1: {e}") from None
        out.append(KalibrCamera(_camera(entry, f"{where}: {name}"), T, str(entry.get("rostopic", "")), name))
        i += 1
    return out


def read_kalibr_camchain(path: str | Path) -> list[KalibrCamera]:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise CalibrationFileError(f"{p}: cannot read ({e})") from None
    return kalibr_cameras(doc, str(p))
