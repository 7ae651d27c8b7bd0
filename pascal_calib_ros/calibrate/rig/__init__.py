"""Camera rigs: the joint problem of N cameras, its start, and the calibration of a rig."""
