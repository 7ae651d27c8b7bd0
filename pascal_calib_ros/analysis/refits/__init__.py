"""Refits: a calibration refitted into another lens model over a region, with the refit's error."""
