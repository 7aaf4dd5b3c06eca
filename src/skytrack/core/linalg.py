"""The one batched linear-algebra layer every filter routes through.

All functions work on stacks of small matrices whose leading axes are tracks, pairs,
modes or Monte Carlo runs (DESIGN.md rule 1).  They are plain numpy; what they add is

* one place for the symmetric-positive-definite conventions of the filters
  (symmetrisation, Cholesky-based solves, ``ln det`` from the Cholesky factor,
  the Mahalanobis distance ``d^2 = nu^T S^-1 nu`` of spec 000 R7), and
* a multiply-add counter: inside ``with counting() as ops:`` every call adds the
  multiply-adds its shapes imply to ``ops.madds`` (by operation name in ``ops.by_name``),
  so that a filter's cost per update (spec 004 R22) is measured, not guessed.  The cost
  model is spec 004 R22's: a product ``(a x b)(b x c)`` costs ``a b c``, a Cholesky
  factorisation of ``n x n`` costs ``n^3 / 3``, a triangular solve with ``r`` right-hand
  sides ``n^2 r`` and an explicit inverse ``n^3``; counts are floats because of the third.

Counting is off by default and costs one global lookup per call when off.
"""

from __future__ import annotations

import contextlib
import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

LOG_2PI = math.log(2.0 * math.pi)


@dataclass
class OperationCount:
    """Multiply-adds counted inside one ``counting()`` block."""

    madds: float = 0.0
    by_name: Counter = field(default_factory=Counter)

    def add(self, name: str, count: float) -> None:
        self.madds += float(count)
        self.by_name[name] += float(count)


_active: list[OperationCount] = []


@contextlib.contextmanager
def counting():
    """Count the multiply-adds of every linalg call in the block (nested blocks all count)."""
    counter = OperationCount()
    _active.append(counter)
    try:
        yield counter
    finally:
        _active.remove(counter)


def is_counting() -> bool:
    """True inside a ``counting()`` block (compiled kernels then report their own counts)."""
    return bool(_active)


def count(name: str, madds: float) -> None:
    """Add ``madds`` multiply-adds under ``name`` to every active counter (for compiled kernels)."""
    for counter in _active:
        counter.add(name, madds)


_count = count


def _batch(*leading: tuple[int, ...]) -> int:
    """Rows of the broadcast batch of the operands' leading shapes."""
    return math.prod(np.broadcast_shapes(*leading))


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Stacked matrix product ``a @ b`` (``b`` may be a stack of vectors ``[..., n]``)."""
    vector = b.ndim == 1 or b.ndim == a.ndim - 1
    out = np.einsum("...ij,...j->...i", a, b) if vector else a @ b
    if _active:
        n_cols = 1 if vector else b.shape[-1]
        rows = _batch(a.shape[:-2], b.shape[:-1] if vector else b.shape[:-2])
        _count("matmul", rows * a.shape[-2] * a.shape[-1] * n_cols)
    return out


def matvec(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Stacked matrix-vector product ``a[..., m, n] v[..., n]`` (either side may be shared)."""
    out = np.einsum("...ij,...j->...i", a, v)
    if _active:
        _count("matvec", _batch(a.shape[:-2], v.shape[:-1]) * a.shape[-2] * a.shape[-1])
    return out


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + P^T) / 2`` over the last two axes."""
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def sandwich(A: np.ndarray, P: np.ndarray, add: np.ndarray | None = None) -> np.ndarray:
    """``A P A^T (+ add)``, symmetrised: the covariance propagation of predict and update."""
    out = A @ P @ np.swapaxes(A, -1, -2)
    if add is not None:
        out = out + add
    if _active:
        m, n = A.shape[-2], A.shape[-1]
        _count("sandwich", _batch(out.shape[:-2]) * (m * n * n + m * n * m))
    return symmetrize(out)


def cholesky(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack of SPD matrices; raises ValueError when one is not SPD."""
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise ValueError("innovation covariance is not positive definite") from None
    if _active:
        m = S.shape[-1]
        _count("cholesky", _batch(S.shape[:-2]) * cholesky_cost(m))
    return L


def cho_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``(L L^T) y = b`` for a stack of vectors ``[..., m]`` or matrices ``[..., m, k]``."""
    vector = b.ndim == L.ndim - 1
    rhs = b[..., None] if vector else b
    w = np.linalg.solve(L, rhs)
    y = np.linalg.solve(np.swapaxes(L, -1, -2), w)
    if _active:
        m = L.shape[-1]
        _count("cho_solve", _batch(L.shape[:-2], rhs.shape[:-2]) * 2 * m * m * rhs.shape[-1])
    return y[..., 0] if vector else y


def mahalanobis_chol(nu: np.ndarray, L: np.ndarray) -> np.ndarray:
    """``d^2 = nu^T S^-1 nu`` with ``S = L L^T`` (one triangular solve)."""
    w = np.linalg.solve(L, nu[..., None])[..., 0]
    if _active:
        m = L.shape[-1]
        _count("mahalanobis", _batch(L.shape[:-2], nu.shape[:-1]) * (m * m + m))
    return np.einsum("...i,...i->...", w, w)


def inv(A: np.ndarray) -> np.ndarray:
    """Explicit inverses of a stack of square matrices (counted as ``n^3`` each, R22)."""
    out = np.linalg.inv(A)
    if _active:
        n = A.shape[-1]
        _count("inv", _batch(A.shape[:-2]) * n**3)
    return out


def cholesky_cost(n: int) -> float:
    """Multiply-adds of an ``n x n`` Cholesky factorisation in the R22 model: ``n^3 / 3``."""
    return n**3 / 3.0


def logdet_chol(L: np.ndarray) -> np.ndarray:
    """``ln det S`` from the Cholesky factor ``L`` of ``S``."""
    return 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)


def gaussian_loglik(d2: np.ndarray, logdet: np.ndarray, m) -> np.ndarray:
    """``ln N(nu; 0, S) = -(d^2 + ln det S + m ln 2 pi) / 2``."""
    return -0.5 * (d2 + logdet + np.asarray(m) * LOG_2PI)


def max_eigenvalue_sym(M: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of symmetric ``[K, 2, 2]`` matrices (exact), an upper bound for larger.

    For more than two dimensions the Gershgorin bound (largest absolute row sum) is used,
    which is all a search radius needs.
    """
    if M.shape[-1] == 2:
        a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 1, 1]
        half_trace = 0.5 * (a + c)
        return half_trace + np.sqrt(np.maximum(0.25 * (a - c) ** 2 + b * b, 0.0))
    return np.max(np.sum(np.abs(M), axis=-1), axis=-1)
