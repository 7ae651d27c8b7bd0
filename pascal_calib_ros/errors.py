"""The package's one base exception.

Every error the package raises on purpose derives from :class:`PascalCalibError` (and from
``ValueError``, as bad input is what they report), so a caller such as the ROS node can tell a
refused input or a failed calibration, which it answers with the message, from a bug, which it
must not swallow. Subclasses say where: :class:`~.targets.TargetError`,
:class:`~.calibrate.pipeline.CalibrationError`, :class:`~.geometry.circular.CircularPointError`,
:class:`~.io.images.ImageReadError`, ...
"""


class PascalCalibError(ValueError):
    """Base of the package's errors: bad input, a degenerate configuration, a refused result."""
