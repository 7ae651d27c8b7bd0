"""Statistics of a calibration: projection uncertainty, residual statistics and the model-bias
verdict, cross-validation, the projection difference of two cameras, a rig's per-camera figures."""
