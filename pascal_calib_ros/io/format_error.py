"""The one error of the calibration file formats (:mod:`.calibration_files` and the modules it reads
and writes with): a file that cannot be read as, or a camera that cannot be written in, a format."""

from __future__ import annotations

from ..errors import PascalCalibError


class CalibrationFileError(PascalCalibError):
    """A calibration file cannot be read (not the format, a field missing or malformed, a lens model
    with no equivalent here) or a camera cannot be written exactly in a format (then the message
    names the refit that would export it: ``pascal-calib export --model ...``)."""


def check_exportable(camera: object, fmt: str) -> None:
    """Refuse a camera with skew: no consumer format (OpenCV's ``projectPoints``, Kalibr, mrcal)
    has a skew term, so it would be dropped silently. ``camera``: a :class:`~..geometry.camera.Camera`."""
    K = camera.K  # type: ignore[attr-defined]
    if K[0, 1] != 0.0:
        raise CalibrationFileError(f"the camera has skew {K[0, 1]:g}; {fmt} has no skew term: export with a refit "
                                   "(--model) or calibrate without --skew")
