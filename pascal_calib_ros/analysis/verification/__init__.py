"""Verification: fresh views against a stored calibration (and hand-eye result), stereo's epipolar
error; a verdict with its numbers."""
