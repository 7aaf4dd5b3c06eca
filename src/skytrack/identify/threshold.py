"""Thresholds of the Neyman–Pearson decision (20a), spec 001 R5 and gap G7.

One :class:`Threshold` is one of three modes:

* ``p_correct=P`` — h = χ²⁻¹_dof(P): under θ = 1 with Q = 0, Λ ~ χ²(dof), so P is the
  probability of correct identification;
* ``p_incorrect=α`` — the paper's NP criterion: h = ncχ²⁻¹_dof(α; λ_d), with λ_d given
  (``noncentrality``), computed as δ^T (P_η + P_ξ)^{-1} δ from a design state difference
  (``state_difference``), or as Δ² λ_min([(P_η + P_ξ)^{-1}]_pos) from a minimum position
  separation Δ (``min_separation_m``: the worst direction, equal velocities);
* ``h=`` — a fixed value (literal; it ignores dof, so its error rates drift with the
  report geometry).

:meth:`Threshold.value` returns h per pair for their dof (and covariances when the mode
needs them).  Rows with dof ≤ 0 get NaN: their decision is ``insufficient`` anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Threshold:
    """A threshold mode of R5; give exactly one of ``p_correct``, ``p_incorrect`` or ``h``."""

    p_correct: float | None = None
    p_incorrect: float | None = None
    noncentrality: float | None = None
    state_difference: tuple[float, ...] | None = None
    min_separation_m: float | None = None
    h: float | None = None

    def __post_init__(self):
        modes = [self.p_correct is not None, self.p_incorrect is not None, self.h is not None]
        if sum(modes) != 1:
            raise ValueError("give exactly one threshold mode: p_correct, p_incorrect or h")
        for name in ("p_correct", "p_incorrect"):
            value = getattr(self, name)
            if value is not None and not 0.0 < value < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {value}")
        if self.p_incorrect is not None:
            designs = [self.noncentrality is not None, self.state_difference is not None,
                       self.min_separation_m is not None]
            if sum(designs) != 1:
                raise ValueError("p_incorrect needs exactly one of noncentrality, state_difference or "
                                 "min_separation_m (the design separation of the foreign object)")
            if self.noncentrality is not None and not self.noncentrality >= 0:
                raise ValueError(f"noncentrality must be >= 0, got {self.noncentrality}")
            if self.min_separation_m is not None and not self.min_separation_m > 0:
                raise ValueError(f"min_separation_m must be > 0, got {self.min_separation_m}")

    @property
    def needs_covariance(self) -> bool:
        """The mode computes λ_d from P_η + P_ξ."""
        return self.p_incorrect is not None and self.noncentrality is None

    def describe(self) -> str:
        if self.h is not None:
            return f"h = {self.h:g} (fixed)"
        if self.p_correct is not None:
            return f"P(correct) = {self.p_correct:g} (h = chi2 quantile for the pair's dof)"
        design = (f"lambda = {self.noncentrality:g}" if self.noncentrality is not None else
                  f"state difference {self.state_difference}" if self.state_difference is not None else
                  f"minimum separation {self.min_separation_m:g} m")
        return f"P(incorrect) = {self.p_incorrect:g} at {design}"

    def design_noncentrality(self, covariance_sum: np.ndarray | None, n_pairs: int) -> np.ndarray:
        """λ_d per pair."""
        if self.noncentrality is not None:
            return np.full(n_pairs, float(self.noncentrality))
        if covariance_sum is None:
            raise ValueError("this threshold mode needs P_eta + P_xi")
        S = np.asarray(covariance_sum, float).reshape(n_pairs, *np.shape(covariance_sum)[-2:])
        S_inv = np.linalg.inv(S)
        if self.state_difference is not None:
            delta = np.asarray(self.state_difference, float)
            if delta.shape[-1] != S.shape[-1]:
                raise ValueError(f"state_difference has {delta.shape[-1]} components; the state has {S.shape[-1]}")
            return np.einsum("i,kij,j->k", delta, S_inv, delta)
        npos = S.shape[-1] // 2 if S.shape[-1] % 2 == 0 else S.shape[-1]
        # the position block of the information matrix; states are position-first (model.py)
        positions = S_inv[:, :npos, :npos]
        return self.min_separation_m ** 2 * np.linalg.eigvalsh(positions)[:, 0]

    def value(self, dof, covariance_sum: np.ndarray | None = None) -> np.ndarray:
        """h per pair for degrees of freedom ``dof`` (NaN where dof ≤ 0)."""
        dof = np.atleast_1d(np.asarray(dof, float))
        valid = dof > 0
        h = np.full(dof.shape, np.nan)
        if self.h is not None:
            h[:] = self.h
            return h
        if self.p_correct is not None:
            h[valid] = stats.chi2.ppf(self.p_correct, dof[valid])
            return h
        lam = self.design_noncentrality(covariance_sum, len(dof))
        central = valid & (lam <= 0)
        h[central] = stats.chi2.ppf(self.p_incorrect, dof[central])
        noncentral = valid & (lam > 0)
        h[noncentral] = stats.ncx2.ppf(self.p_incorrect, dof[noncentral], lam[noncentral])
        return h


def drop_gate(dof, quantile: float = 1.0 - 1e-6) -> np.ndarray:
    """R13 step 5's drop gate: the ``quantile`` of χ²(dof) (NaN where dof ≤ 0)."""
    return Threshold(p_correct=quantile).value(dof)
