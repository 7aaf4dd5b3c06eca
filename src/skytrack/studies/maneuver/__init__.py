"""The manoeuvring-target studies of spec 004 §6 (``skytrack study <name>``) and their framework.

Modules (this package imports none of them itself, so the CLI can list the studies without
loading numpy):

* :mod:`~.trajectory` — exact scripted 3-D legs (straight, coordinated turn, pull-up,
  longitudinal acceleration) (R19);
* :mod:`~.scenarios` — the named scenarios (default, weave, vertical, fighter), scenario
  files, recorded trajectories as cases (R19); :mod:`~.recorded` — truth file to smoothed
  ENU kinematics; :mod:`~.segments` — manoeuvre detection rules;
* :mod:`~.measurements` — polar radar measurements converted with their linearised
  covariance, or Cartesian with a fixed R; run r seeded by ``SeedSequence(seed).spawn(runs)[r]``
  (R21);
* :mod:`~.filters` — the labelled filter catalogue (§6 default parameters);
* :mod:`~.runner` — any protocol filter over the runs: two-point start, NIS/NEES, gating,
  track loss, MACs and wall time per update (R20, R22);
* :mod:`~.metrics` — R20 metrics aligned on manoeuvre onsets;
* :mod:`~.outputs` — summary.csv, timeseries.parquet, figures, claims.json (R23);
* :mod:`~.study` — :class:`~.study.StudyDefinition`, the :class:`~.study.StudyContext` a study
  runs with, :func:`~.study.run_study`;
* :mod:`~.names` — study name -> module (read by the CLI);
* one module per study: :mod:`~.kf_gains` (E2).
"""
