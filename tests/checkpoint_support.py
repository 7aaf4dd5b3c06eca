"""Helpers of the tests that checkpoint a tracker between two chunks of plots
(tests/tracker/test_tracker_checkpoint.py, tests/app/test_app_checkpoint.py)."""

import numpy as np
import pandas as pd

#: plots per chunk: small enough that the demo's 600 s give a few dozen checkpoint places
CHUNK_ROWS = 700


def chunks_of(plots: pd.DataFrame) -> list[pd.DataFrame]:
    return [plots.iloc[start:start + CHUNK_ROWS] for start in range(0, len(plots), CHUNK_ROWS)]


def assert_same_tracks(expected: pd.DataFrame, actual: pd.DataFrame) -> None:
    """Same rows, track ids, times and text columns (statuses, identities); numbers equal to 1e-9 relative."""
    assert len(expected) > 0 and len(actual) == len(expected)
    assert list(actual.columns) == list(expected.columns)
    np.testing.assert_array_equal(actual["track_id"].to_numpy(), expected["track_id"].to_numpy())
    np.testing.assert_array_equal(actual["time"].to_numpy(), expected["time"].to_numpy())
    for column in expected.columns:
        if expected[column].dtype.kind == "f":
            np.testing.assert_allclose(actual[column].to_numpy(), expected[column].to_numpy(), rtol=1e-9, atol=0,
                                       err_msg=column)
        else:
            assert actual[column].astype(object).fillna("<na>").tolist() == \
                expected[column].astype(object).fillna("<na>").tolist(), column
