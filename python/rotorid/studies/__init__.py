"""Sensitivity and Monte Carlo studies of identification accuracy.

- :func:`synchronous_study`, :func:`impact_study`: Monte Carlo studies of a test with the errors of
  :class:`SyncErrors` / :class:`ImpactErrors` (docs/studies.md), run in the core, locally or on a
  Dask cluster; :class:`StudyResult` holds the error percentiles and interval coverage.
- :func:`design_trial_masses`, :func:`design_impact_plan`: rank trial-mass sets and impact plans
  by the expected coefficient error and recommend the best pair and triple.
- :func:`cross_coupling_sensitivity`, :func:`speed_range_errors`: the report's Figure 5 study and
  its speed-range conclusions.
"""

from .errors import ImpactErrors, SyncErrors, frf_random_error
from .monte_carlo import StudyResult, bin_edges, impact_study, percentiles_from_counts, synchronous_study

_LAZY = {"cross_coupling_sensitivity": "sensitivity", "speed_range_errors": "sensitivity",
         **dict.fromkeys(("TrialMassRig", "DesignResult", "design_trial_masses", "design_impact_plan", "dwell_noise_m",
                          "expected_error"), "design")}


def __getattr__(name):
    from importlib import import_module

    if name in _LAZY:
        return getattr(import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ImpactErrors", "StudyResult", "SyncErrors", "bin_edges", "frf_random_error", "impact_study",
           "percentiles_from_counts", "synchronous_study", *_LAZY]
