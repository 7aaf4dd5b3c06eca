"""Spec 002 §6 identifiability studies E1 and E2 (``skytrack study ident-example`` / ``ident-radar``).

* :mod:`~.example` — E1: the paper's 6-state example (§3.5, eq. 14) swept over f16 for f15 ∈ {0, 2}
  (det M, κ, σ_χ; TV1, TV5's unit argument), TV2's local/global timeline (R7, G5) and TV6's window
  (R8, G6);
* :mod:`~.radar_cells` — E2's one-step tables: TV8 (radar parameters and biases, R4/R5) and TV9
  (full state over a window, R8, G3), each computed cell next to the spec's value;
* :mod:`~.radar_track` — E2 along the E3 trajectory: σ_χ(t) of the turn rate for pos, ṙ, pos+ṙ and
  the line-of-sight angle ψ (R9, R10), per-step and global verdicts (R7);
* :mod:`~.radar_setups` — E2's set-up table: ct-omega / ca-accel parameters with sensor biases under
  the measurement sets pos, ṙ, pos+ṙ, polar, polar+ṙ along the trajectory, with culprits (R6, R7).

Every study returns its tables (pandas DataFrames) and :class:`~skytrack.studies.fuzzy.common.Check`
rows, and writes CSV + PNG + a JSON summary.  The checker itself is
:mod:`skytrack.analysis.identifiability` (R5-R10); nothing here re-implements it.
"""
