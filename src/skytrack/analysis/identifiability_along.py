"""Identifiability along a state sequence of an augmented-state model (spec 002 R10).

R10: ``check_along(model, measurement, states, T)`` linearises the model along a given state
sequence x_0 … x_{N-1} — F_k = ∂φ/∂x at x_{k-1} (the paper's F(k|k-1) at x̂(k-1|k-1)) and
H_k = ∂h/∂x at φ(x_{k-1}, T_k) (gap G10: the Jacobian stands in for the paper's linear h) — for
every interval [t_{k-1}, t_k], k = 1 … N-1, and hands the stack to :func:`check_sequence` (R5 per
step, R7 summary, R8 options).  F and H come from one batched call each, the decision from one
batched SVD; no Python loop over steps.

The measurement must be built on the model's states (state dimension = ``model.dim``); sensor
biases are appended to the model with
:func:`skytrack.models.augmented_measurements.augment_for_biases` first.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from skytrack.analysis.identifiability import Method
from skytrack.analysis.identifiability_sequence import IdentifiabilitySequence, Unknown, check_sequence
from skytrack.models.augmented import AugmentedModel
from skytrack.models.augmented_measurements import AugmentedMeasurement


def linearise_along(model: AugmentedModel, measurement: AugmentedMeasurement, states, T):
    """(H, F) of shapes (N-1, m, n) and (N-1, n, n): F_k at x_{k-1}, H_k at φ(x_{k-1}, T_k).

    ``states`` (N, n), N ≥ 2; ``T`` a scalar or the N-1 interval lengths.
    """
    x = np.asarray(states, dtype=float)
    if x.ndim != 2 or len(x) < 2:
        raise ValueError("states must be an (N, n) sequence with N ≥ 2 (N - 1 intervals)")
    if x.shape[1] != model.dim or measurement.state_dim != model.dim:
        raise ValueError(
            f"states have {x.shape[1]} components, model {model.name!r} {model.dim}, "
            f"measurement {measurement.state_dim}; append bias states with augment_for_biases"
        )
    previous = x[:-1]
    steps = np.broadcast_to(np.asarray(T, dtype=float), (len(previous),))
    F = model.F(previous, steps)
    H = measurement.H(model.phi(previous, steps))
    return H, F


def check_along(
    model: AugmentedModel,
    measurement: AugmentedMeasurement,
    states,
    T,
    *,
    noise_cov: np.ndarray | None = None,
    param_scale: np.ndarray | None = None,
    names: Sequence[str] | None = None,
    method: Method = "svd",
    det_tol: float = 0.0,
    window: int = 1,
    unknown: Unknown = "parameters",
) -> IdentifiabilitySequence:
    """R10: R7's record for the intervals k = 1 … N-1 of ``states`` (N, n).

    ``noise_cov`` is V_η (m × m, or (N-1, m, m) per interval).  Names default to the model's
    parameter names (``unknown="all"``: its component names).  The other options are those of
    :func:`~skytrack.analysis.identifiability_sequence.check_sequence`.
    """
    H, F = linearise_along(model, measurement, states, T)
    if names is None:
        names = model.components if unknown == "all" else model.parameters
    return check_sequence(
        H,
        F,
        model.h_a,
        noise_cov=noise_cov,
        param_scale=param_scale,
        names=names,
        method=method,
        det_tol=det_tol,
        window=window,
        unknown=unknown,
    )
