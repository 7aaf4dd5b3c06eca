"""The fuzzy plot-association studies of spec 003 §6 (``skytrack study fuzzy-*``, R20).

Modules (this package imports none of them itself, so the CLI stays light):

* :mod:`~.common` — expected-value checks (``--check``), figure saving, the progress callback type;
* :mod:`~.fig2` — E1, the paper's Fig. 2: Gaussian density vs unit-peak membership (D2);
* :mod:`~.regions` — E2, decision regions of ``ml`` / ``fuzzy`` without and with features
  along the TV9 line (D4, D5, R10);
* :mod:`~.gate` — E3, the effective gate: probability of keeping the correct track against the
  new-object hypothesis vs the feature product Pi, Monte Carlo vs ``F_chi2_4(gamma + 2 ln Pi)``
  (TV11, D5, D6);
* E4 (``fuzzy-crossing``, crossing targets with IFF errors) is a separate module of this package.

Each study function returns its table (a pandas DataFrame) and writes a CSV and a PNG to an
output directory; Monte Carlo draws are seeded explicitly (``np.random.SeedSequence(seed)``).
"""
