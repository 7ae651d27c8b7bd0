"""Intrinsic calibration: closed-form starts (circular points, homographies, plumb lines, Zhang),
the pipeline to a :class:`CalibrationResult`, its checks, options and warm start."""
