"""The solver core: observations, the refinement's problem (residuals, Jacobians, compiled edge
rows), Levenberg-Marquardt with robust reweighting, the sandwich covariance, the refinement."""
