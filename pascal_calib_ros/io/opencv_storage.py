"""OpenCV ``FileStorage`` calibration files: what OpenCV's calibration sample writes and
``cv2.FileStorage`` reads.

Layout written (keys of OpenCV's ``samples/cpp/tutorial_code/calib3d/camera_calibration``, plus
the model named in words)::

    %YAML 1.2          (OpenCV 4 writes %YAML:1.0; both read alike)
    ---
    calibration_time: "2025-01-01T12:00:00Z"
    image_width: 1280
    image_height: 800
    distortion_model: plumb_bob        # plumb_bob | rational_polynomial | equidistant
    fisheye_model: 0                   # 1: use cv::fisheye (equidistant), as the sample writes it
    camera_matrix: !!opencv-matrix     # 3x3 K, rows, cols, dt: d, data
    distortion_coefficients: !!opencv-matrix   # n x 1: 5 (k1 k2 p1 p2 k3), 8 (+ k4 k5 k6), 4 (fisheye k1..k4)

Written and read through ``cv2.FileStorage`` itself (in memory), so what OpenCV reads is what
this module wrote, to the last bit of every double. Reading accepts the other spellings in use
(``cameraMatrix``, ``K``; ``dist_coeffs``, ``distCoeffs``, ``D``; ``image_size`` as [w, h]) and
OpenCV's other vector lengths: 4 (k1 k2 p1 p2, k3 = 0) unless the file says fisheye, 12 and 14
(thin prism, tilt) only when those extra terms are zero. XML and JSON FileStorage files read too.
"""

from __future__ import annotations

import datetime
from pathlib import Path

import cv2
import numpy as np

from ..geometry import Camera
from .format_error import CalibrationFileError, check_exportable

KEYS_K = ("camera_matrix", "cameraMatrix", "K", "intrinsic_matrix")
KEYS_D = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "distortion_coeffs", "D")


def looks_like_opencv_storage(text: str) -> bool:
    """Whether a file's text is an OpenCV FileStorage document (YAML header or matrix tag, XML root)."""
    head = text.lstrip()[:200]
    return head.startswith("%YAML:1.") or "!!opencv-matrix" in text or "<opencv_storage>" in head


def opencv_storage_text(camera: Camera, note: str = "") -> str:
    """The FileStorage YAML of a camera (module docstring); ``note``: comment lines at the top.
    Raises :class:`CalibrationFileError` for a camera with skew (``projectPoints`` ignores it)."""
    check_exportable(camera, "OpenCV's projectPoints")
    fs = cv2.FileStorage("calibration.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for line in note.splitlines():
        fs.writeComment(line)
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    fs.write("calibration_time", stamp)
    fs.write("image_width", int(camera.width))
    fs.write("image_height", int(camera.height))
    fs.write("distortion_model", camera.model)
    fs.write("fisheye_model", 1 if camera.lens.wide else 0)
    fs.write("camera_matrix", np.asarray(camera.K, np.float64))
    fs.write("distortion_coefficients", np.asarray(camera.D, np.float64).reshape(-1, 1))
    return str(fs.releaseAndGetString())


def write_opencv_storage(path: str | Path, camera: Camera, note: str = "") -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(opencv_storage_text(camera, note))
    return p


def _node(fs: cv2.FileStorage, keys: tuple[str, ...]) -> tuple[str, cv2.FileNode] | None:
    for k in keys:
        n = fs.getNode(k)
        if not n.empty():
            return k, n
    return None


def _image_size(fs: cv2.FileStorage, where: str) -> tuple[int, int]:
    w, h = fs.getNode("image_width"), fs.getNode("image_height")
    if not w.empty() and not h.empty():
        return int(w.real()), int(h.real())
    for key in ("image_size", "imageSize", "resolution"):
        n = fs.getNode(key)
        if not n.empty():
            v = n.mat() if n.isMap() else [n.at(i).real() for i in range(n.size())]
            v = np.asarray(v, float).ravel()
            if v.size == 2:
                return int(v[0]), int(v[1])
    raise CalibrationFileError(f"{where}: no image size (image_width and image_height, or image_size)")


def _model(fs: cv2.FileStorage, D: np.ndarray, where: str) -> tuple[str, np.ndarray]:
    """The lens model named in the file (distortion_model, fisheye_model) or implied by len(D)."""
    named = fs.getNode("distortion_model")
    name = named.string() if not named.empty() and named.isString() else ""
    fish = fs.getNode("fisheye_model")
    if not name and not fish.empty() and fish.real() == 1:
        name = "equidistant"
    n = len(D)
    if name == "equidistant":
        if n != 4:
            raise CalibrationFileError(f"{where}: a fisheye (equidistant) model has 4 coefficients, got {n}")
        return "equidistant", D
    if n in (12, 14):
        if np.any(D[8:] != 0):
            raise CalibrationFileError(f"{where}: {n} distortion coefficients with non-zero thin-prism/tilt terms "
                                       f"({D[8:].tolist()}): no equivalent here (plumb_bob: 5, rational_polynomial: 8)")
        D, n = D[:8], 8
    if n == 4:
        D, n = np.r_[D, 0.0], 5
    by_n = {5: "plumb_bob", 8: "rational_polynomial"}
    if n not in by_n:
        raise CalibrationFileError(f"{where}: {n} distortion coefficients match no model (4, 5, 8, 12 or 14; "
                                   "fisheye: 4 with fisheye_model: 1)")
    if name and name != by_n[n]:
        raise CalibrationFileError(f"{where}: distortion_model {name!r} does not match {n} coefficients")
    return by_n[n], D


def camera_from_opencv_text(text: str, where: str = "OpenCV file") -> Camera:
    """The camera of a FileStorage document (YAML, XML or JSON text)."""
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError) as e:  # SystemError: OpenCV's Python binding on a parse error
        why = str(getattr(e, "__cause__", None) or e).strip().splitlines() or ["parse error"]
        raise CalibrationFileError(f"{where}: not an OpenCV FileStorage file ({why[-1]})") from None
    try:
        k = _node(fs, KEYS_K)
        d = _node(fs, KEYS_D)
        if k is None:
            raise CalibrationFileError(f"{where}: no camera matrix (one of {', '.join(KEYS_K)})")
        K = np.asarray(k[1].mat(), float)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or abs(K[2, 2] - 1) > 1e-12 or np.any(K[2, :2] != 0):
            raise CalibrationFileError(f"{where}: {k[0]} is not a 3x3 camera matrix with last row 0 0 1")
        D = np.zeros(5) if d is None else np.asarray(d[1].mat(), float).ravel()
        if not np.all(np.isfinite(D)):
            raise CalibrationFileError(f"{where}: non-finite distortion coefficients")
        model, D = _model(fs, D, where)
        w, h = _image_size(fs, where)
    finally:
        fs.release()
    try:
        return Camera(K, D, w, h, model)
    except ValueError as e:
        raise CalibrationFileError(f"{where}: {e}") from None


def read_opencv_storage(path: str | Path) -> Camera:
    p = Path(path)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"{p}: cannot read ({e})") from None
    return camera_from_opencv_text(text, str(p))
