"""Golden regression: the seeded demo gives the stored tracks table (to 1e-9) and metrics.

The reference was written by ``golden_demo.py`` from the tracker as it stood when the
core restructuring began; a commit that changes tracking behaviour on purpose rewrites it
and says why in its message.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from golden_demo import METRICS_FILE, TRACKS_FILE, run_demo


@pytest.fixture(scope="module")
def demo_run():
    return run_demo()


def test_tracks_table_identical(demo_run):
    tracks, _ = demo_run
    expected = pd.read_parquet(TRACKS_FILE)
    assert list(tracks.columns) == list(expected.columns)
    assert len(tracks) == len(expected)
    for column in expected.columns:
        got, want = tracks[column].to_numpy(), expected[column].to_numpy()
        if want.dtype.kind == "f":
            np.testing.assert_allclose(got.astype(float), want, rtol=1e-9, atol=1e-9, equal_nan=True,
                                       err_msg=f"column {column}")
        else:
            assert [None if pd.isna(v) else v for v in got] == [None if pd.isna(v) else v for v in want], column


def test_metrics_identical(demo_run):
    _, summary = demo_run
    expected = json.loads(METRICS_FILE.read_text())
    assert sorted(summary) == sorted(expected)
    for key, want in expected.items():
        got = summary[key]
        if isinstance(want, float):
            assert (math.isnan(got) and math.isnan(want)) or got == pytest.approx(want, rel=1e-9, abs=1e-9), key
        else:
            assert got == want, key
