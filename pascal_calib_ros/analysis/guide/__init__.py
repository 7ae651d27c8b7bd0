"""Guidance: candidate views, their synthetic observations, the predicted uncertainty each would
leave, and their ranking (person and arm)."""
