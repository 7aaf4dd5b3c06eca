"""Per-step joint observability / identifiability checker of spec 002 (R5, R6, R9), batched over steps.

The paper's criterion is eq. (14): the system is jointly observable and identifiable on
[t_{k-1}, t_k] iff det(Gᵀhᵀh G) ≠ 0, with G = F h_aᵀ (eq. 4) and the one-step sensitivity
S_k = h(k) F(k|k-1) h_aᵀ of eqs. (11)-(12).  As a numerical test the determinant is unusable
(gap G5: it scales with the parameter units, a rounding-level f16 gives det ≈ 4·10⁻³³ ≠ 0, and it
has no margin), so R5 decides on the whitened, column-equilibrated sensitivity instead:

1. S = H G, S̄ = C⁻¹ S diag(d) with V_η = C Cᵀ (whitening makes the test independent of the
   measurement units and weights the channels by their accuracy, G12);
2. influence ratio ρ_j and zero-influence set Z = {j : ρ_j ≤ τ_z};
3. Ŝ = non-Z columns of S̄ divided by their norms; singular values σ_1 ≥ … (σ_i = 0 beyond min(m, q));
4. margin κ = σ_q/σ_1 (0 if Z ≠ ∅), independent of the parameter units;
5. verdict ``not_identifiable`` / ``weak`` / ``identifiable`` with τ_rel = 1e-6, τ_weak = 1e-2;
6. near-null space, weights π_j, indistinguishable set D and the null vectors in parameter units;
7. det(SᵀS) (literal, unwhitened) is always reported, as is ``m < p`` (gap G4: rank(hG) ≤ min(m, p)).

``method="det"`` is the literal eq. (14) with a tolerance (``det_tol``, default 0); the culprit
analysis is still reported.  R6 builds the culprit messages, R9 the one-step precision
σ_χ,j = sqrt([(S̄ᵀS̄)⁻¹]_jj)·d_j of the noise-weighted LS estimate (12) with x(k-1) known (G3: the
dependent state is taken as given).  The sequence summary (R7) and the window / full-state options
(R8, gaps G3 and G6) are in :mod:`skytrack.analysis.identifiability_sequence`.

Everything is vectorised over a leading step axis: one batched SVD, one batched eigen-decomposition;
a zero-influence column is zeroed rather than removed, which leaves the non-zero singular values and
the near-null projector of the remaining columns unchanged and keeps the arrays rectangular.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

# the thresholds and verdict codes of R5 are defined once, beside the filter's per-step check
from skytrack.filters.identifiability_step import (  # noqa: F401  (re-exported)
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    TAU_REL,
    TAU_WEAK,
    TAU_ZERO,
    VERDICT_NAMES,
    WEAK,
)

#: share of a parameter in the near-null space from which it is indistinguishable (R5 step 6)
PI_INDISTINGUISHABLE = 0.01

Method = Literal["svd", "det"]


@dataclass(frozen=True)
class IdentifiabilityChecks:
    """R5's decision for K steps (leading axis), p parameters, m measurement rows.

    ``singular_values`` has p entries per step: those of Ŝ in decreasing order, zero-padded (the
    zero-influence columns and the rows beyond min(m, q) contribute zeros).  ``null_vectors[k][:, i]``
    for ``null_vector_mask[k, i]`` are the near-null directions in parameter units (Z rows zero).
    ``column_norms`` are ‖S̄e_j‖ of the whitened, scaled S.  ``precision`` is σ_χ (R9), NaN where
    it is not defined.  ``steps`` holds the index k of each
    step (interval [t_{k-1}, t_{k+window-1}]).
    """

    names: tuple[str, ...]
    param_scale: np.ndarray
    method: str
    steps: np.ndarray
    window: int
    sensitivity: np.ndarray
    det: np.ndarray
    kappa: np.ndarray
    raw_sigma_ratio: np.ndarray
    singular_values: np.ndarray
    influence_ratio: np.ndarray
    column_norms: np.ndarray
    zero_influence: np.ndarray
    null_space_weight: np.ndarray
    indistinguishable: np.ndarray
    null_vectors: np.ndarray
    null_vector_mask: np.ndarray
    fewer_channels: np.ndarray
    verdict_code: np.ndarray
    precision: np.ndarray

    def __len__(self) -> int:
        return len(self.verdict_code)

    @property
    def verdicts(self) -> list[str]:
        return [VERDICT_NAMES[c] for c in self.verdict_code]

    def zero_influence_names(self, i: int) -> list[str]:
        return [n for n, z in zip(self.names, self.zero_influence[i]) if z]

    def indistinguishable_names(self, i: int) -> list[str]:
        return [n for n, d in zip(self.names, self.indistinguishable[i]) if d]

    def null_vectors_of(self, i: int) -> np.ndarray:
        """The near-null directions of step i in parameter units, one per column (p × r)."""
        return self.null_vectors[i][:, self.null_vector_mask[i]]

    def interval(self, i: int) -> str:
        k = int(self.steps[i])
        return f"[t_{k - 1}, t_{k + self.window - 1}]"

    def messages(self, i: int) -> list[str]:
        """R6 culprit messages of step i (position i along the leading axis)."""
        out = [
            f"parameter {name} has no influence on the measurements over {self.interval(i)}"
            for name in self.zero_influence_names(i)
        ]
        in_d = self.indistinguishable[i]
        for vector in self.null_vectors_of(i).T:
            # a parameter enters the message when its share of the unit equilibrated vector reaches
            # the share that puts it into D; the other components are shown as 0
            share = (vector * self.column_norms[i] / self.param_scale) ** 2
            shown = np.where(share >= PI_INDISTINGUISHABLE, vector, 0.0)
            named = [n for n, d, s in zip(self.names, in_d, shown) if d and s != 0]
            if not named:
                continue
            out.append(
                f"parameters {', '.join(named)} act on the measurements in (nearly) the same way; "
                f"the combination {format_combination(shown, self.names)} is not determined"
            )
        if self.fewer_channels[i]:
            m, p = self.sensitivity.shape[-2:]
            out.append(f"only {m} measurement channels for {p} parameters")
        return out


def format_combination(vector: np.ndarray, names: Sequence[str]) -> str:
    """A null vector as a readable linear combination, e.g. ``0.7071·a1 − 0.7071·a2``."""
    scale = np.abs(vector).max()
    terms = []
    for value, name in zip(vector, names):
        if abs(value) <= 1e-12 * scale:
            continue
        sign = "−" if value < 0 else "+"
        terms.append((sign, f"{abs(value):.4g}·{name}"))
    if not terms:
        return "0"
    first_sign, first = terms[0]
    text = ("−" if first_sign == "−" else "") + first
    return text + "".join(f" {s} {t}" for s, t in terms[1:])


def sensitivity(H: np.ndarray, F: np.ndarray, h_a: np.ndarray) -> np.ndarray:
    """S = H F h_aᵀ = h G (eqs. 4, 11), batched over leading axes."""
    return np.asarray(H, float) @ np.asarray(F, float) @ np.swapaxes(np.asarray(h_a, float), -1, -2)


def _as_batch(a: np.ndarray | None, ndim: int) -> np.ndarray | None:
    if a is None:
        return None
    a = np.asarray(a, dtype=float)
    return a[None] if a.ndim == ndim - 1 else a


def check_identifiability(
    S: np.ndarray | None = None,
    *,
    H: np.ndarray | None = None,
    F: np.ndarray | None = None,
    h_a: np.ndarray | None = None,
    G: np.ndarray | None = None,
    noise_cov: np.ndarray | None = None,
    param_scale: np.ndarray | None = None,
    names: Sequence[str] | None = None,
    method: Method = "svd",
    det_tol: float = 0.0,
    steps: np.ndarray | None = None,
    window: int = 1,
) -> IdentifiabilityChecks:
    """R5 (with R6 messages and R9 precision) for one step or a stack of steps.

    Give either ``S`` ((K,) m × p) or ``H`` ((K,) m × n) with ``G`` ((K,) n × p) or with ``F`` and
    ``h_a`` (G = F h_aᵀ, eq. 4).  ``noise_cov`` is V_η ((K,) m × m, optional), ``param_scale`` the
    p-vector d (default ones).  ``steps`` labels the steps (default 1 … K); ``window`` only sets the
    interval written in the messages (see :mod:`~skytrack.analysis.identifiability_sequence`).
    """
    if method not in ("svd", "det"):
        raise ValueError(f"method must be 'svd' or 'det', not {method!r}")
    if S is None:
        if H is None:
            raise ValueError("give S, or H with G or with F and h_a")
        H = _as_batch(H, 3)
        if G is None:
            if F is None or h_a is None:
                raise ValueError("H needs G, or F and h_a")
            G = np.asarray(F, float) @ np.asarray(h_a, float).T
        G = _as_batch(G, 3)
        batch = max(len(H), len(G))
        H = np.broadcast_to(H, (batch, *H.shape[1:]))
        G = np.broadcast_to(G, (batch, *G.shape[1:]))
        S = H @ G
    else:
        S = _as_batch(S, 3)
        H = None
    K, m, p = S.shape
    d = np.ones(p) if param_scale is None else np.asarray(param_scale, float)
    if d.shape != (p,) or np.any(d <= 0):
        raise ValueError("param_scale must be a positive p-vector")
    names = tuple(names) if names is not None else tuple(f"a{j + 1}" for j in range(p))
    if len(names) != p:
        raise ValueError(f"{len(names)} names for {p} parameters")

    # step 1: whitening and parameter scaling
    if noise_cov is not None:
        cov = np.broadcast_to(_as_batch(noise_cov, 3), (K, m, m))
        chol = np.linalg.cholesky(cov)
        S_white = np.linalg.solve(chol, S)
        H_white = np.linalg.solve(chol, H) if H is not None else None
    else:
        S_white, H_white = S, H
    S_bar = S_white * d
    column_norm = np.linalg.norm(S_bar, axis=-2)

    # step 2: influence ratio and zero-influence set
    if H_white is not None:
        bound = np.linalg.norm(H_white, ord=2, axis=(-2, -1))[:, None] * np.linalg.norm(G, axis=-2) * d
    else:
        bound = np.broadcast_to(column_norm.max(axis=-1, keepdims=True), column_norm.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(bound > 0, column_norm / np.where(bound > 0, bound, 1.0), 0.0)
    zero = rho <= TAU_ZERO

    # step 3: equilibrated SVD, zero-influence columns zeroed
    safe_norm = np.where(zero, 1.0, column_norm)
    S_hat = np.where(zero[:, None, :], 0.0, S_bar / safe_norm[:, None, :])
    _, sigma_short, Vh = np.linalg.svd(S_hat, full_matrices=True)
    sigma = np.zeros((K, p))
    sigma[:, : sigma_short.shape[1]] = sigma_short
    V = np.swapaxes(Vh, -1, -2)

    # step 4: margin
    sigma_1 = sigma[:, 0]
    any_zero = zero.any(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        kappa = np.where(any_zero | (sigma_1 <= 0), 0.0, sigma[:, -1] / np.where(sigma_1 > 0, sigma_1, 1.0))

    # step 5: verdict
    svd_code = np.where(
        any_zero | (kappa <= TAU_REL), NOT_IDENTIFIABLE, np.where(kappa <= TAU_WEAK, WEAK, IDENTIFIABLE)
    )
    det = np.linalg.det(np.swapaxes(S, -1, -2) @ S)
    if method == "det":
        code = np.where(np.abs(det) > det_tol, IDENTIFIABLE, NOT_IDENTIFIABLE)
    else:
        code = svd_code

    # step 6 and R9
    weight, indistinguishable, null_vectors, vector_mask = _near_null_space(V, sigma, zero, safe_norm, d)
    precision = np.full((K, p), np.nan)
    defined = (code != NOT_IDENTIFIABLE) & (svd_code != NOT_IDENTIFIABLE)
    if noise_cov is not None and defined.any():
        precision[defined] = _precision(V[defined], sigma[defined], safe_norm[defined], d)

    # G5: the unequilibrated ratio σ_min/σ_max of S, which moves with the parameter units
    raw_sigma = np.linalg.svd(S, compute_uv=False)
    raw_max = raw_sigma[:, 0]
    raw_ratio = np.where(raw_max > 0, raw_sigma[:, -1] / np.where(raw_max > 0, raw_max, 1.0), 0.0)
    if m < p:
        raw_ratio = np.zeros(K)

    return IdentifiabilityChecks(
        names=names,
        param_scale=d,
        method=method,
        steps=np.arange(1, K + 1) if steps is None else np.asarray(steps),
        window=window,
        sensitivity=S,
        det=det,
        kappa=kappa,
        raw_sigma_ratio=raw_ratio,
        singular_values=sigma,
        influence_ratio=rho,
        column_norms=column_norm,
        zero_influence=zero,
        null_space_weight=weight,
        indistinguishable=indistinguishable,
        null_vectors=null_vectors,
        null_vector_mask=vector_mask,
        fewer_channels=np.full(K, m < p),
        verdict_code=code,
        precision=precision,
    )


def _near_null_space(
    V: np.ndarray, sigma: np.ndarray, zero: np.ndarray, column_norm: np.ndarray, d: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """R5 step 6 for the non-zero-influence columns: π_j, D, null vectors in parameter units, their mask.

    The near-null space of the zeroed Ŝ is that of the kept columns plus the unit vectors of Z; the
    projector restricted to the kept coordinates is therefore the kept columns' own projector, whose
    diagonal is π (basis-independent) and whose unit eigenvectors are the null vectors.
    """
    in_null = sigma <= TAU_WEAK * sigma[:, :1]
    V_null = V * in_null[:, None, :]
    keep = (~zero).astype(float)
    projector = (V_null @ np.swapaxes(V_null, -1, -2)) * keep[:, :, None] * keep[:, None, :]
    weight = np.clip(np.diagonal(projector, axis1=-2, axis2=-1), 0.0, 1.0)
    indistinguishable = (~zero) & (weight >= PI_INDISTINGUISHABLE)
    eigenvalues, eigenvectors = np.linalg.eigh(projector)
    # Ŝ v = 0 ⇔ S diag(d / ‖S̄e_j‖) v = 0: the parameter-unit direction is v_j d_j / ‖S̄e_j‖
    null_vectors = eigenvectors * (keep * d / column_norm)[:, :, None]
    largest = np.take_along_axis(null_vectors, np.abs(null_vectors).argmax(axis=1)[:, None, :], axis=1)
    null_vectors = null_vectors * np.where(largest < 0, -1.0, 1.0)
    return weight, indistinguishable, null_vectors, eigenvalues > 0.5


def _precision(V: np.ndarray, sigma: np.ndarray, column_norm: np.ndarray, d: np.ndarray) -> np.ndarray:
    """R9: σ_χ,j = sqrt([(S̄ᵀS̄)⁻¹]_jj) d_j, with (S̄ᵀS̄)⁻¹ = diag(1/‖S̄e‖) V Σ⁻² Vᵀ diag(1/‖S̄e‖)."""
    inverse_diag = np.einsum("kji,ki->kj", V**2, 1.0 / sigma**2)
    return np.sqrt(inverse_diag) / column_norm * d
