"""Studies over many runs of one scene: parameter sweeps and imperfection sensitivity.

``shellform study imperfection SCENE --out DIR`` traces the perfect structure
to its first critical point, then many imperfect ones (its buckling modes,
random combinations of them, or Gaussian random fields, at a list of
amplitudes) each to the load at which it first loses stability, and writes
the knock-down curves, the distribution of the critical load factor with a
fractile and its confidence interval, and the worst sample's path. The
samples run on the runner sweeps use (:mod:`shellform.studies.runner`). See
``docs/imperfections.md``.

Modules: ``runner`` (where runs go: this process, a process pool, Dask),
``sweep`` with ``sweep_cases`` and ``sweep_table`` (``shellform sweep``),
``settings`` (the ``[study]`` table), ``shapes``, ``sample`` (one imperfect
structure), ``statistics``, ``imperfection`` (the study), ``link_models``
(the closed forms it is validated against).
"""

from .imperfection import StudyError, StudyOptions, run_imperfection_study
from .settings import StudySettings, study_settings

__all__ = ["StudyError", "StudyOptions", "StudySettings", "run_imperfection_study", "study_settings"]
