"""Accuracy studies against ground truth, the seed paper's experiments and the benchmarks
(``pascal-calib study``, ``experiment``, ``bench``): each a module run on demand, none imported by
the library."""

from .bench import run_bench
from .boards_study import boards_study
from .experiments import run_experiment
from .guided_study import run_guided_study
from .handeye_study import run_handeye_study
from .model_bias_study import model_bias_study
from .stereo_study import stereo_study
from .study import run_study
from .trust_study import trust
from .undesigned_views import undesigned_views
from .verify_study import StudySpec, verify_study

__all__ = ["StudySpec", "bench", "boards_study", "experiments", "handeye_study", "model_bias_study", "run_bench",
           "run_experiment", "run_guided_study", "run_handeye_study", "run_study", "stereo_study", "study", "trust",
           "trust_study", "undesigned_views", "verify_study"]
