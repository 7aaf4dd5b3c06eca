"""The identification studies of spec 001 §6 (``skytrack study ident-*``).

Modules (this package imports none of them itself, so the CLI stays light):

* :mod:`~.common` — expected-value checks, JSON summaries, figure saving, Monte Carlo chunks;
* :mod:`~.potential_study` — E1 / E2, the paper's Figs. 1 and 2: P_ПО, P_НО(A) and the averaged
  P̄_НО against the normalised threshold r, with an ROC panel and a Monte Carlo confirmation
  (R9, (26)-(28b), TV-1);
* :mod:`~.np_design` — E3, the Neyman-Pearson design: P_ПО against the allowed P_НО = alpha for
  A = 2..6 and for the uniform-separation average (R10, TV-1);
* :mod:`~.elliptic` — E4, the elliptical-scattering claim (G10): Monte Carlo of the distance test
  with sigma_x != sigma_y against the circular formulas with sigma = sigma_x, and the normalised
  statistic (27) against chi2_2 / ncx2_2;
* :mod:`~.scenario_tv5`, :mod:`~.mc_common` — the TV-5 scenario, its batch quadratic forms and
  the Monte Carlo helpers of E5-E9;
* :mod:`~.sequential_mc` — E5 / R16, Λ against χ²(4) and ncχ²(4, λ);
* :mod:`~.quadratic_forms` — E6, four quadratic forms against the joint-only two;
* :mod:`~.process_noise` — E7, Λ with process noise (exact by Imhof), fuse and track-state tests;
* :mod:`~.posterior_calibration` — E8, the posterior with and without the log-determinants (G1);
* :mod:`~.many_to_many` — E9, global against greedy assignment over 30 objects.

Each study returns its tables (pandas DataFrames) and writes a CSV, a PNG and a JSON summary to an
output folder; Monte Carlo draws are seeded explicitly (``np.random.SeedSequence(seed)``).
"""
