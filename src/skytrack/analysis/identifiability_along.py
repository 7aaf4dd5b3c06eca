"""Identifiability along a state sequence of an augmented-state model (spec 002 R10).

R10: ``check_along(model, measurement, states, T)`` linearises the model along a given state
sequence x_0 … x_{N-1} — F_k = ∂φ/∂x at x_{k-1} (the paper's F(k|k-1) at x̂(k-1|k-1)) and
H_k = ∂h/∂x at φ(x_{k-1}, T_k) (gap G10: the Jacobian stands in for the paper's linear h) — for
every interval [t_{k-1}, t_k], k = 1 … N-1, and hands the stack to :func:`check_sequence` (R5 per
step, R7 summary, R8 options).  F and H come from one batched call each, the decision from one
batched SVD; no Python loop over steps.  :func:`check_along_tracks` does the same for a bank of
tracks (B, N, n) in one batched linearisation and one batched decision, split into one R7 record per
track (windows never straddle two tracks).

The measurement must be built on the model's states (state dimension = ``model.dim``); sensor
biases are appended to the model with
:func:`skytrack.models.augmented_measurements.augment_for_biases` first.
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Sequence

import numpy as np

from skytrack.analysis.identifiability import IdentifiabilityChecks, Method, check_identifiability
from skytrack.analysis.identifiability_sequence import (
    IdentifiabilitySequence,
    Unknown,
    block_diagonal,
    check_sequence,
)
from skytrack.models.augmented import AugmentedModel
from skytrack.models.augmented_measurements import AugmentedMeasurement


def linearise_along(model: AugmentedModel, measurement: AugmentedMeasurement, states, T):
    """(H, F) of shapes (N-1, m, n) and (N-1, n, n): F_k at x_{k-1}, H_k at φ(x_{k-1}, T_k).

    ``states`` (N, n), N ≥ 2; ``T`` a scalar or the N-1 interval lengths.
    """
    x = np.asarray(states, dtype=float)
    if x.ndim not in (2, 3) or x.shape[-2] < 2:
        raise ValueError("states must be an (N, n) sequence or (B, N, n) tracks with N ≥ 2 (N - 1 intervals)")
    if x.shape[-1] != model.dim or measurement.state_dim != model.dim:
        raise ValueError(
            f"states have {x.shape[-1]} components, model {model.name!r} {model.dim}, "
            f"measurement {measurement.state_dim}; append bias states with augment_for_biases"
        )
    previous = x[..., :-1, :]
    lead = previous.shape[:-1]
    flat = previous.reshape(-1, model.dim)
    steps = np.broadcast_to(np.asarray(T, dtype=float), lead).reshape(-1)
    F = model.F(flat, steps)
    H = measurement.H(model.phi(flat, steps))
    return H.reshape(*lead, *H.shape[-2:]), F.reshape(*lead, *F.shape[-2:])


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
    if H.ndim != 3:
        raise ValueError("check_along takes one (N, n) sequence; use check_along_tracks for (B, N, n)")
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


#: fields of IdentifiabilityChecks that describe all steps alike (not sliced per track)
_SHARED_FIELDS = ("names", "param_scale", "method", "window")


def _split(checks: IdentifiabilityChecks, tracks: int) -> list[IdentifiabilitySequence]:
    per_track = len(checks) // tracks
    out = []
    for b in range(tracks):  # per track, not per step: slices of the batched result
        rows = slice(b * per_track, (b + 1) * per_track)
        sliced = {f.name: getattr(checks, f.name)[rows] for f in fields(checks) if f.name not in _SHARED_FIELDS}
        out.append(IdentifiabilitySequence(replace(checks, **sliced)))
    return out


def check_along_tracks(
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
) -> list[IdentifiabilitySequence]:
    """R10 for a bank of tracks: ``states`` (B, N, n), ``T`` scalar, (N-1,) or (B, N-1); one R7
    record per track, equal to :func:`check_along` on that track.

    ``noise_cov`` is V_η (m × m) or per interval (B, N-1, m, m).  The decisions of all tracks and
    steps are one batched SVD; windows (R8) are stacked within each track.
    """
    H, F = linearise_along(model, measurement, states, T)
    if H.ndim != 4:
        raise ValueError("check_along_tracks needs states of shape (B, N, n)")
    B, K, m, n = H.shape
    count = K - window + 1
    if window < 1 or count < 1:
        raise ValueError(f"window must be between 1 and the {K} intervals of a track")
    if names is None:
        names = model.components if unknown == "all" else model.parameters
    influence = F if unknown == "all" else F @ model.h_a.T
    # R8's stacked observation within each track: [H_k; H_{k+1}F_{k+1}; …], windows as a loop over offsets
    propagated = np.broadcast_to(np.eye(n), (B, count, n, n))
    blocks = [H[:, :count]]
    for offset in range(1, window):
        propagated = F[:, offset : offset + count] @ propagated
        blocks.append(H[:, offset : offset + count] @ propagated)
    observation = np.concatenate(blocks, axis=-2).reshape(B * count, window * m, n)
    cov = None
    if noise_cov is not None:
        cov = np.broadcast_to(np.asarray(noise_cov, float), (B, K, m, m))
        windows = np.stack([cov[:, j : j + count] for j in range(window)], axis=2)
        cov = block_diagonal(windows.reshape(B * count, window, m, m))
    checks = check_identifiability(
        H=observation,
        G=influence[:, :count].reshape(B * count, *influence.shape[-2:]),
        noise_cov=cov,
        param_scale=param_scale,
        names=names,
        method=method,
        det_tol=det_tol,
        steps=np.tile(np.arange(1, count + 1), B),
        window=window,
    )
    return _split(checks, B)
