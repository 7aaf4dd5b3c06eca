"""skytrack.studies: the studies of the papers, one module per paper study.

* :mod:`~skytrack.studies.singer_missed` — spec 000 §6: Singer filtering and one-scan
  extrapolation accuracy with missed detections (``skytrack study singer-missed``).

Studies sit above the simulator and the analysis tools in the package order, so they may
use both.  Every Monte Carlo loop seeds run r with ``np.random.SeedSequence(seed).spawn(runs)[r]``,
so a run's result does not depend on how the runs are batched or distributed.
"""
