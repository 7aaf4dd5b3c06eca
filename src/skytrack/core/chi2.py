"""Chi-square quantile and distribution function from scipy.special.

``scipy.stats`` takes about half a second to import, and the filter registry imports every
filter family when a tracker starts: the gates and tests of the families use these two
functions instead (the same values as ``scipy.stats.chi2.ppf`` and ``.cdf``).
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammainc, gammaincinv


def chi2_quantile(probability, dof):
    """``chi2_dof^-1(probability)`` = 2 P^-1(dof / 2, probability), P the regularised lower
    incomplete gamma function; arrays broadcast."""
    value = 2.0 * gammaincinv(0.5 * np.asarray(dof, dtype=float), np.asarray(probability, dtype=float))
    return float(value) if np.ndim(value) == 0 else value


def chi2_cdf(x, dof):
    """``P(chi2_dof <= x)`` = P(dof / 2, x / 2); arrays broadcast."""
    value = gammainc(0.5 * np.asarray(dof, dtype=float), 0.5 * np.asarray(x, dtype=float))
    return float(value) if np.ndim(value) == 0 else value
