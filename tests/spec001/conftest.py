"""Shared report streams of spec 001's test vectors (TV-3, TV-4, TV-7)."""

import numpy as np
import pytest

RADAR = [(0.0, 1032.0, 2023.0), (1.0, 1068.0, 1891.0), (2.0, 1193.0, 1960.0), (3.0, 1367.0, 1895.0)]
ADSB_SAME = [(0.3, 1037.0, 2017.0), (1.3, 1155.0, 1931.0), (2.3, 1209.0, 1878.0), (3.3, 1322.0, 1849.0)]
ADSB_DIFF = [(t, x + 150.0, y - 100.0) for t, x, y in ADSB_SAME]
V_RADAR, V_ADSB = 50.0 ** 2 * np.eye(2), 20.0 ** 2 * np.eye(2)


def tv3_stream(case: str):
    """(time, system, z, V) of TV-3's merged reports for case 'same' or 'diff'."""
    adsb = ADSB_SAME if case == "same" else ADSB_DIFF
    time = np.array([r[0] for r in RADAR] + [a[0] for a in adsb])
    system = np.array([1] * 4 + [2] * 4)
    z = np.array([r[1:] for r in RADAR] + [a[1:] for a in adsb])
    V = np.array([V_RADAR] * 4 + [V_ADSB] * 4)
    return time, system, z, V


@pytest.fixture
def tv3():
    return tv3_stream
