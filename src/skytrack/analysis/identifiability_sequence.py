"""Local and global identifiability along a step sequence, windows and full state (spec 002 R7, R8).

R7: the paper calls eq. (14) holding on one interval [t_{k-1}, t_k] *local* and holding on every
interval of the analysed span *global* observability / identifiability (§3.4; gap G7: the example
prints both sentences alike).  :func:`check_sequence` runs the per-step checker of
:mod:`skytrack.analysis.identifiability` (R5) on all steps at once and :class:`IdentifiabilitySequence`
gives the global verdict (the worst local one), the failing steps and per-parameter counts of Z and D.

R8 (improvement, default off): one step is sufficient, not necessary (gap G6) — an influence that
reaches the measurements only after two steps is invisible to eq. (14).  ``window=N_w`` stacks
S^(N_w) = [H_k G_k; H_{k+1} F_{k+1} G_k; …; H_{k+N_w-1} F_{k+N_w-1}⋯F_{k+1} G_k] with block-diagonal
V_η; ``unknown="all"`` puts F_k in place of G_k = F_k h_aᵀ, i.e. observability of the whole x(k-1),
the case the paper leaves out (gap G3).  Only full windows are formed: a sequence of K steps gives
K − N_w + 1 windowed steps, labelled by their first step k.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

from skytrack.analysis.identifiability import (
    NOT_IDENTIFIABLE,
    VERDICT_NAMES,
    WEAK,
    IdentifiabilityChecks,
    Method,
    check_identifiability,
)

Unknown = Literal["parameters", "all"]


@dataclass(frozen=True)
class IdentifiabilitySequence:
    """R7's record: the per-step checks and the global summary over them."""

    checks: IdentifiabilityChecks

    @property
    def steps(self) -> np.ndarray:
        return self.checks.steps

    @property
    def verdicts(self) -> list[str]:
        return self.checks.verdicts

    @property
    def global_verdict(self) -> str:
        return VERDICT_NAMES[int(self.checks.verdict_code.min())]

    @property
    def failing_steps(self) -> list[int]:
        """Steps k whose local verdict is ``not_identifiable``."""
        return [int(k) for k in self.steps[self.checks.verdict_code == NOT_IDENTIFIABLE]]

    @property
    def weak_steps(self) -> list[int]:
        return [int(k) for k in self.steps[self.checks.verdict_code == WEAK]]

    @property
    def zero_influence_count(self) -> dict[str, int]:
        return dict(zip(self.checks.names, self.checks.zero_influence.sum(axis=0).tolist()))

    @property
    def indistinguishable_count(self) -> dict[str, int]:
        return dict(zip(self.checks.names, self.checks.indistinguishable.sum(axis=0).tolist()))

    def messages(self) -> list[str]:
        """All culprit messages (R6), step by step, for the steps that are not identifiable or weak."""
        out = []
        for i in np.flatnonzero(self.checks.verdict_code != VERDICT_NAMES.index("identifiable")):
            out.extend(f"k = {int(self.steps[i])}: {text}" for text in self.checks.messages(int(i)))
        return out


def block_diagonal(blocks: np.ndarray) -> np.ndarray:
    """(K, W, m, m) → (K, W·m, W·m) block-diagonal matrices."""
    K, W, m, _ = blocks.shape
    out = np.zeros((K, W, m, W, m))
    index = np.arange(W)
    out[:, index, :, index, :] = np.moveaxis(blocks, 1, 0)
    return out.reshape(K, W * m, W * m)


def stacked_observation(H: np.ndarray, F: np.ndarray, window: int) -> np.ndarray:
    """O_k = [H_k; H_{k+1}F_{k+1}; …; H_{k+N_w-1}F_{k+N_w-1}⋯F_{k+1}] for every full window (R8).

    ``H`` (K, m, n) and ``F`` (K, n, n) hold H_k, F(k|k-1) for k = 1 … K along axis 0.
    """
    K, m, n = H.shape
    count = K - window + 1
    if count < 1:
        raise ValueError(f"window {window} is longer than the {K} steps")
    propagated = np.broadcast_to(np.eye(n), (count, n, n))
    blocks = [H[:count]]
    for offset in range(1, window):
        propagated = F[offset : offset + count] @ propagated
        blocks.append(H[offset : offset + count] @ propagated)
    return np.concatenate(blocks, axis=1)


def check_sequence(
    H: np.ndarray,
    F: np.ndarray,
    h_a: np.ndarray | None = None,
    *,
    noise_cov: np.ndarray | None = None,
    param_scale: np.ndarray | None = None,
    names: Sequence[str] | None = None,
    method: Method = "svd",
    det_tol: float = 0.0,
    window: int = 1,
    unknown: Unknown = "parameters",
    first_step: int = 1,
) -> IdentifiabilitySequence:
    """R5 on every step k = first_step … of a sequence, with the R8 options, summarised per R7.

    ``H`` (K, m, n) or (m, n) for all steps, ``F`` (K, n, n), ``noise_cov`` V_η(k) as (K, m, m) or
    (m, m).  ``unknown="parameters"`` (paper) needs ``h_a``; ``"all"`` checks the whole state x(k-1)
    and names default to x1 … xn.
    """
    F = np.asarray(F, float)
    F = F[None] if F.ndim == 2 else F
    K, n, _ = F.shape
    H = np.broadcast_to(np.asarray(H, float), (K, *np.asarray(H).shape[-2:]))
    m = H.shape[1]
    if window < 1:
        raise ValueError("window must be ≥ 1")
    if unknown == "all":
        influence = F
        if names is None:
            names = tuple(f"x{i + 1}" for i in range(n))
    elif unknown == "parameters":
        if h_a is None:
            raise ValueError('unknown="parameters" needs h_a')
        influence = F @ np.asarray(h_a, float).T
    else:
        raise ValueError(f'unknown must be "parameters" or "all", not {unknown!r}')
    count = K - window + 1
    observation = stacked_observation(H, F, window)
    cov = None
    if noise_cov is not None:
        cov = np.broadcast_to(np.asarray(noise_cov, float), (K, m, m))
        cov = block_diagonal(np.stack([cov[j : j + count] for j in range(window)], axis=1))
    checks = check_identifiability(
        H=observation,
        G=influence[:count],
        noise_cov=cov,
        param_scale=param_scale,
        names=names,
        method=method,
        det_tol=det_tol,
        steps=np.arange(first_step, first_step + count),
        window=window,
    )
    return IdentifiabilitySequence(checks)


def summarize(checks: IdentifiabilityChecks) -> IdentifiabilitySequence:
    """R7's record for checks computed directly with :func:`check_identifiability` (e.g. from S_k)."""
    return IdentifiabilitySequence(checks)
