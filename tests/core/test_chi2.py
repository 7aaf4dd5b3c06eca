"""skytrack.core.chi2 against scipy.stats (imported here only: the tracker does not import it)."""

import numpy as np
import pytest
from scipy import stats

from skytrack.core.chi2 import chi2_cdf, chi2_quantile


@pytest.mark.parametrize("probability, dof", [(0.99, 2), (0.975, 400), (0.5, 1), (1 - 1e-6, 6), (0.025, 4.5)])
def test_quantile_and_cdf_equal_scipy_stats(probability, dof):
    quantile = chi2_quantile(probability, dof)
    assert quantile == pytest.approx(stats.chi2.ppf(probability, dof), rel=1e-12)
    assert chi2_cdf(quantile, dof) == pytest.approx(probability, rel=1e-12)
    assert chi2_cdf(quantile, dof + 2) == pytest.approx(stats.chi2.cdf(quantile, dof + 2), rel=1e-12)


def test_arrays_broadcast_and_scalars_stay_floats():
    values = chi2_quantile(0.99, np.array([1, 2, 3]))
    np.testing.assert_allclose(values, [6.634896601021, 9.210340371976, 11.344866730144], rtol=1e-11)
    assert isinstance(chi2_quantile(0.99, 2), float) and isinstance(chi2_cdf(3.0, 2), float)


def test_starting_a_tracker_does_not_import_scipy_stats():
    """scipy.stats costs about half a second at start-up; the filter families avoid it."""
    import subprocess
    import sys

    code = ("import sys; from skytrack.tracker import Tracker; from skytrack.filters.registry import FILTERS; "
            "'imm' in FILTERS; print('scipy.stats' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
