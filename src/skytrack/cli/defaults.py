"""Defaults of the ``skytrack track`` options that mirror :class:`skytrack.tracker.TrackerConfig`.

They are written out here because importing ``TrackerConfig`` imports numpy and scipy,
and ``skytrack --help`` must answer without them.  ``tests/cli/test_cli_defaults.py``
asserts that every option default equals the dataclass field default, so the two cannot
drift apart: change a default in ``TrackerConfig`` and that test names this file.
"""

MODEL = "cv"
CV_Q = 0.5
SINGER_TAU_S = 20.0
SINGER_SIGMA_A = 4.0
DISCRETIZATION = "exact"
P_GATE = 0.9995
CONFIRM_M = 3
CONFIRM_N = 4
DELETE_MISSES = 5
INIT = "one-point"
TRACK_LOGIC = "score"
FALSE_TRACKS_PER_HOUR = 1.0
REPORT_MAX_MISSES = 4
#: plots per chunk of ``skytrack track`` (mirrors :data:`skytrack.app.run.DEFAULT_CHUNK_ROWS`)
CHUNK_ROWS = 200_000
