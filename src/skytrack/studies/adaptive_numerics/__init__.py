"""Numerical studies of spec 002 §6 on the adaptive augmented filter and its diagnostics.

* :mod:`.gain_conditioning` — E5, conditioning of gain (6) and of the covariance update (R11 A7, A8);
* :mod:`.poor_experiment` — E6, the poorly-planned-experiment diagnostic on TV12(b)'s remedies (R16);
* :mod:`.vw_estimator` — E7, the V_w estimator of eq. (7) as implemented (R12, R13; TV11 c, d);
* :mod:`.common` — expected-value checks and the CSV / PNG / JSON outputs shared by the three.

The commands are ``skytrack study gain-conditioning / poor-experiment / vw-estimator``
(:mod:`skytrack.cli.study_adaptive_numerics`).
"""
