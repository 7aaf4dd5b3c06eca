"""core.linalg against direct numpy/scipy on random SPD batches, and its multiply-add counter.

Counts are the shape-implied multiply-adds the module documents: ``a[..., i, j] @ b[..., j, k]``
counts ``i j k`` per matrix, ``A P A^T`` counts ``m n n + m n m``, a Cholesky factor ``m^3 // 6 + m``,
a Cholesky solve ``m^2`` per right-hand side and ``d^2`` ``m^2 // 2 + m``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from skytrack.core import linalg

DIMS = [1, 2, 3, 6]


def random_spd(rng, rows, m, cond=1e3):
    """SPD ``[rows, m, m]`` with eigenvalues spread over ``cond`` and random orientation."""
    Q, _ = np.linalg.qr(rng.standard_normal((rows, m, m)))
    eig = np.exp(rng.uniform(0.0, np.log(cond), (rows, m))) * rng.uniform(0.1, 100.0, (rows, 1))
    return (Q * eig[:, None, :]) @ np.swapaxes(Q, -1, -2)


def rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(np.max(np.abs(b)), 1e-300))


@pytest.fixture
def rng():
    return np.random.default_rng(20240605)


# ---------------------------------------------------------------------------- values
def test_matmul_matrix_and_vector(rng):
    a, b = rng.standard_normal((10, 3, 4)), rng.standard_normal((10, 4, 5))
    explicit = np.array([[[sum(a[k, i, l] * b[k, l, j] for l in range(4)) for j in range(5)] for i in range(3)]
                         for k in range(10)])
    assert rel(linalg.matmul(a, b), explicit) < 1e-14
    v = rng.standard_normal((10, 4))
    assert rel(linalg.matmul(a, v), np.array([a[k] @ v[k] for k in range(10)])) < 1e-14
    assert linalg.matmul(a, v).shape == (10, 3)


@pytest.mark.parametrize("m", DIMS)
def test_symmetrize(rng, m):
    P = rng.standard_normal((20, m, m))
    S = linalg.symmetrize(P)
    assert np.array_equal(S, np.swapaxes(S, -1, -2))
    assert np.array_equal(S, 0.5 * (P + np.swapaxes(P, -1, -2)))
    sym = random_spd(rng, 20, m)
    sym = 0.5 * (sym + np.swapaxes(sym, -1, -2))
    assert np.array_equal(linalg.symmetrize(sym), sym)


@pytest.mark.parametrize("m", DIMS)
def test_sandwich(rng, m):
    n = m + 2
    A, P, add = rng.standard_normal((20, m, n)), random_spd(rng, 20, n), random_spd(rng, 20, m)
    for extra in (None, add):
        out = linalg.sandwich(A, P, extra)
        direct = np.array([A[k] @ P[k] @ A[k].T + (0 if extra is None else extra[k]) for k in range(20)])
        assert rel(out, direct) < 1e-12
        assert np.array_equal(out, np.swapaxes(out, -1, -2))


@pytest.mark.parametrize("m", DIMS)
def test_cholesky(rng, m):
    S = random_spd(rng, 30, m)
    L = linalg.cholesky(S)
    assert rel(L, np.linalg.cholesky(S)) < 1e-14
    assert np.array_equal(L, np.tril(L)) and np.all(np.einsum("kii->ki", L) > 0)
    assert rel(L @ np.swapaxes(L, -1, -2), S) < 1e-12


@pytest.mark.parametrize("bad", [
    np.array([[1.0, 2.0], [2.0, 1.0]]),  # indefinite (eigenvalues 3, -1)
    np.array([[1.0, 1.0], [1.0, 1.0]]),  # singular PSD
    np.array([[-1.0]]),
])
def test_cholesky_of_non_spd_raises_value_error(rng, bad):
    m = len(bad)
    batch = random_spd(rng, 4, m)
    batch[2] = bad
    with pytest.raises(ValueError, match="positive definite"):
        linalg.cholesky(batch)
    with pytest.raises(ValueError):
        linalg.cholesky(bad)


@pytest.mark.parametrize("m", DIMS)
def test_cho_solve(rng, m):
    S = random_spd(rng, 30, m)
    L = linalg.cholesky(S)
    b = rng.standard_normal((30, m))
    assert rel(linalg.cho_solve(L, b), np.linalg.solve(S, b[..., None])[..., 0]) < 1e-9
    B = rng.standard_normal((30, m, 4))
    y = linalg.cho_solve(L, B)
    assert y.shape == (30, m, 4)
    assert rel(y, np.linalg.inv(S) @ B) < 1e-9
    assert rel(S @ y, B) < 1e-9


@pytest.mark.parametrize("m", DIMS)
def test_mahalanobis_and_logdet(rng, m):
    S = random_spd(rng, 30, m)
    L = linalg.cholesky(S)
    nu = rng.standard_normal((30, m)) * 10.0
    direct = np.array([nu[k] @ np.linalg.inv(S[k]) @ nu[k] for k in range(30)])
    assert rel(linalg.mahalanobis_chol(nu, L), direct) < 1e-10
    assert rel(linalg.logdet_chol(L), np.log(np.linalg.det(S))) < 1e-12
    assert rel(linalg.logdet_chol(L), np.linalg.slogdet(S)[1]) < 1e-12


@pytest.mark.parametrize("m", DIMS)
def test_gaussian_loglik(rng, m):
    S = random_spd(rng, 30, m)
    L = linalg.cholesky(S)
    nu = rng.standard_normal((30, m)) * 5.0
    got = linalg.gaussian_loglik(linalg.mahalanobis_chol(nu, L), linalg.logdet_chol(L), m)
    direct = np.array([-0.5 * (nu[k] @ np.linalg.inv(S[k]) @ nu[k] + math.log(np.linalg.det(S[k]))
                               + m * math.log(2 * math.pi)) for k in range(30)])
    assert rel(got, direct) < 1e-12
    scipy_value = np.array([stats.multivariate_normal(np.zeros(m), S[k]).logpdf(nu[k]) for k in range(30)])
    assert rel(got, scipy_value) < 1e-10
    assert linalg.LOG_2PI == math.log(2 * math.pi)
    # per-row measured dimension m[K]
    dims = np.arange(30) % 3 + 1
    np.testing.assert_allclose(linalg.gaussian_loglik(np.ones(30), np.zeros(30), dims),
                               -0.5 * (1.0 + dims * math.log(2 * math.pi)), rtol=1e-15)


def test_max_eigenvalue_sym(rng):
    M2 = random_spd(rng, 50, 2)
    M2 = 0.5 * (M2 + np.swapaxes(M2, -1, -2))
    assert rel(linalg.max_eigenvalue_sym(M2), np.linalg.eigvalsh(M2)[:, -1]) < 1e-12
    indefinite = np.array([[[1.0, 3.0], [3.0, -2.0]]])
    assert rel(linalg.max_eigenvalue_sym(indefinite), np.linalg.eigvalsh(indefinite)[:, -1]) < 1e-14
    for m in (3, 6):
        M = random_spd(rng, 50, m)
        bound = linalg.max_eigenvalue_sym(M)
        assert np.all(bound >= np.linalg.eigvalsh(M)[:, -1] * (1 - 1e-12))  # an upper bound
        assert np.array_equal(bound, np.abs(M).sum(axis=-1).max(axis=-1))  # Gershgorin


# ---------------------------------------------------------------------------- counting
def known_counts(rng):
    """(name, call, expected multiply-adds) for K = 10 rows."""
    K = 10
    a, b = rng.standard_normal((K, 3, 4)), rng.standard_normal((K, 4, 5))
    S = random_spd(rng, K, 3)
    L = np.linalg.cholesky(S)
    return [
        ("matmul", lambda: linalg.matmul(a, b), K * 3 * 4 * 5),
        ("matmul", lambda: linalg.matmul(a, b[..., 0]), K * 3 * 4),
        ("sandwich", lambda: linalg.sandwich(a, random_spd(rng, K, 4)), K * (3 * 4 * 4 + 3 * 4 * 3)),
        ("sandwich", lambda: linalg.sandwich(a, random_spd(rng, K, 4), S), K * (3 * 4 * 4 + 3 * 4 * 3)),
        ("cholesky", lambda: linalg.cholesky(S), K * 9.0),
        ("cho_solve", lambda: linalg.cho_solve(L, rng.standard_normal((K, 3))), K * 2 * 9),
        ("cho_solve", lambda: linalg.cho_solve(L, rng.standard_normal((K, 3, 4))), K * 2 * 9 * 4),
        ("mahalanobis", lambda: linalg.mahalanobis_chol(rng.standard_normal((K, 3)), L), K * (9 + 3)),
        ("inv", lambda: linalg.inv(S), K * 27),
    ]


def test_known_counts_for_known_shapes(rng):
    for name, call, expected in known_counts(rng):
        with linalg.counting() as ops:
            call()
        assert ops.madds == expected, name
        assert dict(ops.by_name) == {name: expected}
    with linalg.counting() as ops:
        linalg.matmul(rng.standard_normal((10, 3, 4)), rng.standard_normal((10, 4, 5)))
    assert ops.madds == 10 * 3 * 4 * 5 == 600


def test_uncounted_helpers_record_nothing(rng):
    S = random_spd(rng, 5, 3)
    L = np.linalg.cholesky(S)
    with linalg.counting() as ops:
        linalg.symmetrize(S)
        linalg.logdet_chol(L)
        linalg.gaussian_loglik(np.ones(5), np.ones(5), 3)
        linalg.max_eigenvalue_sym(S)
    assert ops.madds == 0 and not ops.by_name


def test_nested_blocks_both_count_and_off_records_nothing(rng):
    a, b = rng.standard_normal((10, 3, 4)), rng.standard_normal((10, 4, 5))
    S = random_spd(rng, 10, 3)
    with linalg.counting() as outer:
        linalg.matmul(a, b)  # 600
        with linalg.counting() as inner:
            linalg.cholesky(S)  # 90
            linalg.matmul(a, b)  # 600
        assert inner.madds == 690 and inner.by_name == {"cholesky": 90, "matmul": 600}
        linalg.matmul(a, b[..., 0])  # 120
    assert outer.madds == 600 + 690 + 120
    assert outer.by_name == {"matmul": 1320, "cholesky": 90}
    assert outer.madds == sum(outer.by_name.values())
    # counting off: nothing is recorded anywhere, and finished counters stay as they were
    assert linalg._active == []
    linalg.matmul(a, b)
    linalg.cholesky(S)
    assert (outer.madds, inner.madds) == (1410, 690)
    assert linalg._active == []


def test_counter_is_removed_when_the_block_raises(rng):
    with pytest.raises(ValueError):
        with linalg.counting() as ops:
            linalg.matmul(rng.standard_normal((2, 2, 2)), rng.standard_normal((2, 2, 2)))
            linalg.cholesky(np.array([[[1.0, 2.0], [2.0, 1.0]]]))
    assert ops.madds == 16 and ops.by_name == {"matmul": 16}  # the failed Cholesky is not counted
    assert linalg._active == []


def test_operation_count_add():
    ops = linalg.OperationCount()
    ops.add("x", 3)
    ops.add("y", np.int64(4))
    ops.add("x", 2)
    assert ops.madds == 9 and ops.by_name == {"x": 5, "y": 4}
    assert isinstance(ops.madds, float)  # R22 counts n^3/3 for a Cholesky factorisation


@pytest.mark.parametrize("case", ["matmul-one-vector", "cho_solve-shared-L", "mahalanobis-shared-L"])
def test_counts_follow_the_broadcast_batch(rng, case):
    K = 10
    S = random_spd(rng, 1, 3)[0]
    L = np.linalg.cholesky(S)
    calls = {
        "matmul-one-vector": (lambda: linalg.matmul(rng.standard_normal((K, 3, 4)), rng.standard_normal(4)), K * 3 * 4),
        "cho_solve-shared-L": (lambda: linalg.cho_solve(L, rng.standard_normal((K, 3, 2))), K * 2 * 9 * 2),  # two triangular solves
        "mahalanobis-shared-L": (lambda: linalg.mahalanobis_chol(rng.standard_normal((K, 3)), L), K * (9 + 3)),
    }
    call, expected = calls[case]
    with linalg.counting() as ops:
        out = call()
    assert len(out) == K  # the values are batched ...
    assert ops.madds == expected  # ... the count is not


def test_matvec_broadcasts_a_shared_matrix_over_a_batch_of_vectors(rng):
    """F [n, n] shared by vectors x [K, n] (the case a plain ``@`` gets wrong), counted per row."""
    F = rng.standard_normal((4, 4))
    x = rng.standard_normal((10, 4))
    with linalg.counting() as ops:
        out = linalg.matvec(F, x)
    np.testing.assert_allclose(out, x @ F.T, rtol=1e-13)
    assert ops.madds == 10 * 4 * 4
