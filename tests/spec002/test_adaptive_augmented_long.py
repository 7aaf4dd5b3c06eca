"""Spec 002 TV11 (c): long run of the V_w estimator (R12 A5.4 with λ = 1, innovation weighting), full length.

20 seeds are run as one bank of 20 tracks (each track has its own truth and noise), 20 001 measurements.
"""

import numpy as np
import pytest

@pytest.mark.slow
def test_tv11c_innovation_weighting_converges_to_V_w(tv11_bank):
    state, _ = tv11_bank(20, 20_001, lambda k: 0.5, seed=11)
    final = state.V_bar[:, 0, 0]
    assert np.all((final >= 0.22) & (final <= 0.28)), final
    assert 0.24 <= final.mean() <= 0.26, final.mean()
