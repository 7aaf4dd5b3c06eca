"""Names of the spec 004 §6 studies and the modules that define them (light: no heavy imports).

The CLI registers ``skytrack study <name>`` for every entry; each module holds
``STUDY = StudyDefinition(...)`` (:mod:`skytrack.studies.maneuver.study`).  A new study is one
module plus one line here.
"""

from __future__ import annotations

import importlib

#: study name -> (module, one-line help)
STUDY_MODULES: dict[str, tuple[str, str]] = {
    "ab-range": ("skytrack.studies.maneuver.ab_range",
                 "E1 (P1): the paper's alpha-beta range tracker: noise, lag and track loss over alpha and range acceleration"),
    "kf-gains": ("skytrack.studies.maneuver.kf_gains",
                 "E2 (P2, P3): KF gain histories, alpha-beta-gamma = steady-state KF, KF-CV error in a turn"),
    "ie-bank": ("skytrack.studies.maneuver.ie_bank",
                "E4 (P8): input estimation, accuracy and multiply-adds against the onset-bank size N_w"),
    "berg-frame": ("skytrack.studies.maneuver.berg_frame",
                   "E5 (P9): Berg-type model, full 9x9 KF vs target-frame blocks: cost and error"),
    "reduced-cost": ("skytrack.studies.maneuver.reduced_cost",
                     "E8 (P3, P4): per-axis, transformed-gain, piecewise-gain KF and alpha-beta-gamma vs the coupled KF"),
    "bounded-noise": ("skytrack.studies.maneuver.bounded_noise",
                      "E9 (paper item 6): set-membership filter under bounded and Gaussian noise, containment, violations"),
    "tracker-synthesis": ("skytrack.studies.maneuver.tracker_synthesis",
                          "E10 (P12): range rate per motion state, IMM model set per situation, manoeuvre-library IMM"),
    "adaptive-qr": ("skytrack.studies.maneuver.adaptive_qr",
                    "E6 (P10): adaptive Q/R estimation (structured, Sage-Husa, covariance matching) with and without IE"),
    "maneuver-compare": ("skytrack.studies.maneuver.maneuver_compare",
                         "E3 (P5-P7, P11): every filter family on manoeuvring targets: RMS, loss, NEES, detection delay, cost"),
    "multiple-model": ("skytrack.studies.maneuver.multiple_model",
                       "E7 (P11, P12): static bank (literal, improved) vs IMM per model set and scenario, switch-off"),
}


def load_study(name: str):
    """The :class:`~skytrack.studies.maneuver.study.StudyDefinition` of a study name."""
    if name not in STUDY_MODULES:
        raise ValueError(f"unknown study {name!r}; studies: {', '.join(sorted(STUDY_MODULES))}")
    return importlib.import_module(STUDY_MODULES[name][0]).STUDY
