"""Spec 002 §6 E3/E4 study ``skytrack study turn-rate-adaptive``: non-stationary turn-rate identification
with the adaptive augmented filter (R11-R14; E4: gap G11, no dependent-state noise).

* :mod:`.scenario` — truth (CT with piecewise ω), measurements, windows, configurations, prototype numbers;
* :mod:`.simulation` — batched runs of the adaptive augmented filter (R11-R14) and of spec 004's IMM;
* :mod:`.metrics` — window RMSE, divergence, tables with the prototype beside each figure, E3/E4 checks;
* :mod:`.figures` — ω̂(t) vs truth, median √V̂_w(t) with the floor, RMSE(t);
* :mod:`.study` — the driver writing CSV, PNG and JSON.
"""
