"""Plots fed in fixed chunks, for the tests that checkpoint a tracker between two chunks
(tests/tracker/test_tracker_checkpoint.py, tests/app/test_app_checkpoint.py)."""

import pandas as pd

#: plots per chunk: small enough that the demo's 600 s give a few dozen checkpoint places
CHUNK_ROWS = 700


def chunks_of(plots: pd.DataFrame) -> list[pd.DataFrame]:
    return [plots.iloc[start:start + CHUNK_ROWS] for start in range(0, len(plots), CHUNK_ROWS)]
