"""Spec 001 R16 / TV-5: Monte Carlo validation of the sequential test, and TV-5a/b/c closed forms.

The Monte Carlo runs N = 1e5 report streams per case with the vectorised GLS forms (Λ = z^T A z, as
the spec did), so the tolerances are TV-5's own for N = 1e5; the GLS forms are checked against the
library's recursive filters on 300 runs (and that check is shown to catch a wrong model).  TV-5c's
exact values come from the eigenvalues of the quadratic form (Imhof); its Monte Carlo check runs
N = 2e5 per q, the spec's N, with its tolerances (var ± 3 %, probability ± 0.0015).
"""

import numpy as np
import pytest
from scipy import integrate, stats

from skytrack.studies.identification import process_noise as e7
from skytrack.studies.identification import scenario_tv5 as tv5
from skytrack.studies.identification import sequential_mc as e5

N = 100_000


@pytest.fixture(scope="module")
def samples():
    return e5.simulate(N, seed=11, cases=(e5.THETA_1, "+100 m in x"))


def test_tv5a_separate_covariances_closed_form():
    P_eta, P_xi = tv5.separate_covariances()
    axis = np.ix_([0, 2], [0, 2])
    for name, P, times, sigma in (("radar", P_eta, tv5.TV5_GEOMETRY.times_eta, 50.0),
                                  ("adsb", P_xi, tv5.TV5_GEOMETRY.times_xi, 20.0)):
        np.testing.assert_allclose(P[axis], tv5.TV5A[name], atol=1e-6)
        np.testing.assert_allclose(P[np.ix_([1, 3], [1, 3])], tv5.TV5A[name], atol=1e-6)  # the y axis too
        np.testing.assert_allclose(tv5.closed_form_covariance(times, sigma, 9.3), tv5.TV5A[name], atol=1e-6)


@pytest.mark.parametrize("case", list(tv5.OFFSETS))
def test_tv5b_noncentrality_and_probability_columns(case):
    """λ by the closed form and by μ^T A μ (1e-5); the probability columns to 1e-6 relative (or half a unit
    of the table's last digit where it prints fewer digits; '≈1' as > 1 - 1e-6)."""
    spec = dict(zip(tv5.TV5B_COLUMNS, tv5.TV5B[case]))
    lam = tv5.closed_form_noncentrality(tv5.OFFSETS[case])
    assert lam == pytest.approx(spec["lambda"], abs=1e-5)
    assert tv5.offset_noncentrality(tv5.TV5_GEOMETRY, tv5.OFFSETS[case]) == pytest.approx(spec["lambda"], abs=1e-5)
    row = tv5.tv5b_row(lam)
    for column in tv5.TV5B_COLUMNS[1:]:
        if spec[column] is None:
            assert row[column] > 1.0 - 1e-6, column
        else:
            assert row[column] == pytest.approx(spec[column], abs=tv5.table_tolerance(spec[column])), column


def test_table_tolerance_reads_the_printed_digits():
    assert tv5.table_tolerance(0.064522) == pytest.approx(5e-7)
    assert tv5.table_tolerance(0.5968379) == pytest.approx(0.5968379e-6)
    assert tv5.table_tolerance(4.743487e-17) == pytest.approx(4.743487e-23)


def test_r16_theta1_chi2_4(samples):
    lam = samples[e5.THETA_1]["statistic"]
    assert len(lam) == N
    assert lam.mean() == pytest.approx(4.0, abs=0.05)
    assert lam.var(ddof=1) == pytest.approx(8.0, abs=0.4)
    assert np.mean(lam <= 13.276704) == pytest.approx(0.99, abs=0.0016)
    assert stats.kstest(lam, stats.chi2(4).cdf).pvalue > 1e-4


def test_r16_theta0_plus_100m_noncentral(samples):
    lam = samples["+100 m in x"]["statistic"]
    assert lam.mean() == pytest.approx(38.438, abs=0.2)
    assert lam.var(ddof=1) == pytest.approx(145.75, abs=7.0)
    assert np.mean(lam <= 13.276704) == pytest.approx(0.0054, abs=0.0012)
    assert stats.kstest(lam, stats.ncx2(4, 34.438087).cdf).pvalue > 1e-4


@pytest.mark.parametrize("case,lam", [(e5.THETA_1, 0.0), ("+100 m in x", 34.438087)])
def test_r16_separate_and_joint_forms(samples, case, lam):
    values = samples[case]
    assert values["J_eta"].mean() == pytest.approx(16.0, abs=0.1)
    assert values["J_xi"].mean() == pytest.approx(16.0, abs=0.1)
    assert values["J_joint"].mean() == pytest.approx(36.0 + lam, abs=0.25)
    np.testing.assert_allclose(values["statistic"], values["J_joint"] - values["J_eta"] - values["J_xi"])


def test_gls_forms_equal_recursive_filters():
    worst = e5.recursive_check(seed=5, runs=300)
    assert max(worst.values()) <= 1e-8


def test_the_recursive_check_catches_a_wrong_form():
    """The same check with the GLS matrices of another model (q = 25) must see the difference."""
    rng = np.random.default_rng(2)
    z = tv5.draw_reports(rng, 50, tv5.TV5_GEOMETRY)
    recursive, _ = tv5.recursive_forms(z, tv5.TV5_GEOMETRY, q=0.0)
    wrong = tv5.evaluate_forms(z, tv5.quadratic_forms(tv5.TV5_GEOMETRY, q=25.0))
    right = tv5.evaluate_forms(z, tv5.quadratic_forms(tv5.TV5_GEOMETRY, q=0.0))
    assert np.max(np.abs(recursive.statistic - right["statistic"])) <= 1e-8
    assert np.max(np.abs(recursive.statistic - wrong["statistic"])) > 1e-3


@pytest.mark.parametrize("q", sorted(tv5.TV5C))
def test_tv5c_exact_moments_and_coverage(q):
    """E Λ = 4, var Λ and P(Λ ≤ χ²_4(0.99)) from the eigenvalues, within the table's digits (5e-7)."""
    mean, var, probability = tv5.TV5C[q]
    weights = tv5.statistic_eigenvalues(tv5.TV5_GEOMETRY, q)
    got_mean, got_var = tv5.exact_moments(weights)
    assert got_mean == pytest.approx(mean, abs=1e-9)
    assert got_var == pytest.approx(var, abs=5e-7)
    assert tv5.imhof_cdf(tv5.H_99, weights) == pytest.approx(probability, abs=5e-7)


def test_tv5c_polarised_matrix_is_the_gls_form():
    """The exact statistic's matrix rebuilt from the recursive filters (E7) equals the GLS form."""
    matrices = e7.statistic_matrices(25.0)
    np.testing.assert_allclose(matrices["exact"], tv5.quadratic_forms(tv5.TV5_GEOMETRY, 25.0).statistic, atol=1e-12)


def test_imhof_against_chi2_and_a_convolution():
    for k in (2, 4):
        for x in (0.5, 4.0, 13.276704):
            assert tv5.imhof_cdf(x, np.ones(k)) == pytest.approx(stats.chi2.cdf(x, k), abs=1e-9)
    # A - B/2 with A, B ~ chi2_2: P(A - B/2 <= x) = int P(A <= x + b/2) f_B(b) db
    x = 1.5
    reference = integrate.quad(lambda b: stats.chi2.cdf(x + 0.5 * b, 2) * stats.chi2.pdf(b, 2), 0, np.inf)[0]
    assert tv5.imhof_cdf(x, [1.0, 1.0, -0.5, -0.5]) == pytest.approx(reference, abs=1e-9)


@pytest.mark.parametrize("q", [25.0, 400.0])
def test_tv5c_monte_carlo_with_process_noise(q):
    """N = 2e5 truths with white-noise acceleration q: var ± 3 %, P ± 0.0015 (TV-5c); recursive = forms."""
    matrices = {q: e7.statistic_matrices(q)}
    samples, recursive = e7.simulate(matrices, 200_000, seed=4)
    lam = samples[q]["exact"]
    _, var, probability = tv5.TV5C[q]
    assert lam.var(ddof=1) == pytest.approx(var, rel=0.03)
    assert np.mean(lam <= tv5.H_99) == pytest.approx(probability, abs=0.0015)
    assert lam.mean() == pytest.approx(4.0, abs=4 * np.sqrt(var / len(lam)))
    assert recursive[q] <= 1e-6
