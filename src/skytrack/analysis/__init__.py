"""skytrack.analysis: metrics against truth, the evaluation of tracker output and report figures
(the studies of the papers live in :mod:`skytrack.studies`).

* :mod:`~skytrack.analysis.metrics` — OSPA, GOSPA (with its decomposition), RMSE, NEES;
* :mod:`~skytrack.analysis.evaluate` — :func:`evaluate` tracks against truth (``skytrack evaluate``);
  its parts: ``checks``, ``instants``, ``truth`` (visible runs, coverage), ``covariances``, ``evaluation``;
* :mod:`~skytrack.analysis.report` — PPI plan view and metrics-over-time figures.
"""

from skytrack.analysis.evaluate import (
    CONFIRMED_STATUSES,
    Evaluation,
    coverage_check,
    evaluate,
    infer_output_times,
    truth_visible_runs,
)
from skytrack.analysis.metrics import (
    GospaResult,
    Matching,
    SetMetricSeries,
    cutoff_matching,
    euclidean_errors,
    gospa,
    in_intervals,
    nees,
    nees_band,
    ospa,
    rmse,
    set_metrics_over_time,
    set_metrics_stacked,
)

# report figures import matplotlib: loaded on first use so that `import skytrack.analysis`
# (e.g. by the CLI's evaluate) stays fast
_REPORT_NAMES = ("plot_metrics_over_time", "plot_positions", "plot_ppi")


def __getattr__(name: str):
    if name in _REPORT_NAMES:
        from skytrack.analysis import report

        return getattr(report, name)
    raise AttributeError(f"module 'skytrack.analysis' has no attribute {name!r}")


__all__ = [
    # metrics
    "GospaResult",
    "Matching",
    "SetMetricSeries",
    "cutoff_matching",
    "euclidean_errors",
    "gospa",
    "in_intervals",
    "nees",
    "nees_band",
    "ospa",
    "rmse",
    "set_metrics_over_time",
    "set_metrics_stacked",
    # evaluation
    "CONFIRMED_STATUSES",
    "Evaluation",
    "coverage_check",
    "evaluate",
    "infer_output_times",
    "truth_visible_runs",
    # figures
    "plot_metrics_over_time",
    "plot_positions",
    "plot_ppi",
]
