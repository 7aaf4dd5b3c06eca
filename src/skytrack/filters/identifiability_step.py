"""Per-step identifiability verdict used inside the adaptive augmented filter (spec 002 R5 steps 1-5, R11 A4).

The filter needs only the verdict, the margin κ and the zero-influence set of R5 for each track of a
bank at each step; the full record with culprit messages, near-null space and precision (R5 step 6,
R6, R9) is :func:`skytrack.analysis.identifiability.check_identifiability`, which sits in a higher
layer and must not be imported by a filter.  The thresholds and verdict codes are the same as there
(TV1, TV2, TV8 pin them in the analysis tests); a test of the filter checks that both agree.

Algorithm (batched over a leading axis): S = H G; whitening S̄ = C⁻¹S with V_η = CCᵀ (gap G12);
influence ratio ρ_j = ‖S̄e_j‖ / (‖C⁻¹H‖₂‖Ge_j‖); Z = {j : ρ_j ≤ τ_z}; κ = σ_q/σ_1 of the
column-equilibrated S̄ (0 if Z ≠ ∅; σ_i = 0 beyond min(m, q), gap G4); verdict
``not_identifiable`` if Z ≠ ∅ or κ ≤ τ_rel, ``weak`` if κ ≤ τ_weak, else ``identifiable`` (gap G5:
no determinant test).
"""

from __future__ import annotations

import numpy as np

#: zero-influence threshold on ρ_j (R5 step 2)
TAU_ZERO = 1e-10
#: κ at or below which the parameters are not identifiable (R5 step 5)
TAU_REL = 1e-6
#: κ at or below which identification is weak (R5 step 5)
TAU_WEAK = 1e-2
#: verdict codes, worst first (skytrack.analysis.identifiability uses these)
NOT_IDENTIFIABLE, WEAK, IDENTIFIABLE = 0, 1, 2
VERDICT_NAMES = ("not_identifiable", "weak", "identifiable")


def step_verdicts(H: np.ndarray, G: np.ndarray, noise_cov: np.ndarray):
    """R5 verdict for a bank: H ``[N, m, n]``, G ``[N, n, p]``, V_η ``[N, m, m]``.

    Returns ``(code [N] int, kappa [N], zero_influence [N, p] bool)``.
    """
    H = np.asarray(H, float)
    G = np.asarray(G, float)
    chol = np.linalg.cholesky(np.asarray(noise_cov, float))
    H_white = np.linalg.solve(chol, H)
    S_white = H_white @ G
    N, m, p = S_white.shape
    column_norm = np.linalg.norm(S_white, axis=-2)
    bound = np.linalg.norm(H_white, ord=2, axis=(-2, -1))[:, None] * np.linalg.norm(G, axis=-2)
    positive = bound > 0
    rho = np.where(positive, column_norm / np.where(positive, bound, 1.0), 0.0)
    zero = rho <= TAU_ZERO
    safe_norm = np.where(zero, 1.0, column_norm)
    S_hat = np.where(zero[:, None, :], 0.0, S_white / safe_norm[:, None, :])
    sigma_short = np.linalg.svd(S_hat, compute_uv=False)
    sigma = np.zeros((N, p))
    sigma[:, : sigma_short.shape[1]] = sigma_short
    sigma_1 = sigma[:, 0]
    any_zero = zero.any(axis=1)
    kappa = np.where(any_zero | (sigma_1 <= 0), 0.0, sigma[:, -1] / np.where(sigma_1 > 0, sigma_1, 1.0))
    code = np.where(any_zero | (kappa <= TAU_REL), NOT_IDENTIFIABLE,
                    np.where(kappa <= TAU_WEAK, WEAK, IDENTIFIABLE))
    return code.astype(int), kappa, zero
