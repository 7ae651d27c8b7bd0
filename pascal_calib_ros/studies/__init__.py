"""Accuracy studies against ground truth, the seed paper's experiments and the benchmarks
(``pascal-calib study``, ``experiment``, ``bench``): each a module run on demand, none imported by
the library."""

__all__ = ["bench", "experiments", "handeye_study", "model_bias_study", "study", "trust_study"]
