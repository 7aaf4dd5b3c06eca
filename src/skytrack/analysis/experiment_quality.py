"""Poorly-planned-experiment diagnostic of spec 002 §3.6 (R16, the decision for gap G9).

The paper: "a substantial excess of the absolute values of the elements of the estimate-error
covariance matrix over the diagonal elements of the measurement-error covariance matrix is evidence of
a poorly planned experiment", to be cured by (1) fewer parameters, (2) more measurement data,
(3) prior information.  It gives no threshold and compares variances of states whose units differ
from the measurements' (G9).  R16 makes it a test:

- ``mode="literal"``: ratio(k) = max_ij |P_ij(k|k)| / max_l V_η,ll(k); component i is flagged when
  P_ii ≥ 10^κ_o max_l V_η,ll (for a PSD matrix the largest element is on the diagonal);
- ``mode="matched"`` (default): each component is compared with a reference variance r_i of its own
  unit — the user's, else the smallest measurement variance of a channel of the same unit, else none
  ("no reference", never flagged); flagged when P_ii ≥ 10^κ_o r_i;
- a step is flagged when any component is; the run is a "poorly planned experiment" when at least a
  fraction f of the steps k > burn_in are flagged (a run of ≤ burn_in steps: its last step decides);
- the advice is the paper's three remedies in a fixed wording, filled with the culprits of R5/R7,
  the measurement channels acting on the flagged components, and the flagged components themselves.

Defaults: κ_o = 2 (factor 100), burn_in = 20 steps, f = 0.5.  :func:`covariance_recursion` is the
deterministic linear Kalman covariance recursion (fixed V_w, eqs. 3-6 with Joseph update) used by
TV12(b) and study E6.  Everything is vectorised over the step axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Mapping, Sequence

import numpy as np

#: default orders of magnitude κ_o (threshold factor 10^κ_o)
ORDERS = 2.0
#: default number of initial steps excluded from the run verdict
BURN_IN = 20
#: default share of flagged steps after the burn-in that makes the run poorly planned
FRACTION = 0.5

Mode = Literal["matched", "literal"]


@dataclass(frozen=True)
class ExperimentQuality:
    """R16's record for K steps (leading axis) of an n-component state.

    ``literal_ratio`` is max|P_ij| / max V_η,ll for every step whatever the mode; ``reference`` the
    per-step reference variance of each component in the chosen mode (NaN: no reference) and
    ``component_ratio`` = P_ii / reference.  ``considered`` marks the steps that enter the verdict.
    """

    mode: str
    orders: float
    burn_in: int
    fraction: float
    components: tuple[str, ...]
    steps: np.ndarray
    literal_ratio: np.ndarray
    reference: np.ndarray
    component_ratio: np.ndarray
    flagged_components: np.ndarray
    flagged_steps: np.ndarray
    considered: np.ndarray
    advice: str | None

    @property
    def flagged_fraction(self) -> float:
        return float(self.flagged_steps[self.considered].mean())

    @property
    def poorly_planned(self) -> bool:
        return self.advice is not None

    @property
    def verdict(self) -> str:
        return "poorly planned experiment" if self.poorly_planned else "ok"

    @property
    def culprit_components(self) -> tuple[str, ...]:
        """Components flagged at some step that enters the verdict."""
        flagged = self.flagged_components[self.considered].any(axis=0)
        return tuple(name for name, f in zip(self.components, flagged) if f)

    def no_reference(self) -> tuple[str, ...]:
        """Components without a reference variance (matched mode), reported, never flagged."""
        missing = np.isnan(self.reference).all(axis=0)
        return tuple(name for name, m in zip(self.components, missing) if m)


def advice_text(
    components: Sequence[str],
    orders: float = ORDERS,
    culprits: Sequence[str] = (),
    channels: Sequence[str] = (),
) -> str:
    """R16's fixed advice wording; an empty bracket (no culprits, no channels) is left out."""

    def bracket(text: str, names: Sequence[str]) -> str:
        return f" ({text}{', '.join(names)})" if names else ""

    flagged = ", ".join(components)
    return (
        f"Estimate-error variances of {flagged} exceed the measurement-error variances by more than "
        f"10^{orders:g}: the experiment is poorly planned. Revise first the mathematical models in use, "
        f"then (1) reduce the dimension of the parameter vector of the state model"
        f"{bracket('not identifiable from the measurements: ', culprits)}; "
        f"(2) bring in additional measurement data{bracket('channels acting on them: ', channels)}; "
        f"(3) use the available prior information{bracket('tighter priors on ', components)}."
    )


def culprits_of(record) -> tuple[str, ...]:
    """Parameters in Z or D at any step of an R5 or R7 record (for the advice's remedy 1)."""
    checks = getattr(record, "checks", record)
    involved = checks.zero_influence.any(axis=0) | checks.indistinguishable.any(axis=0)
    return tuple(name for name, c in zip(checks.names, involved) if c)


def _batch(a, ndim: int) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    return a[None] if a.ndim == ndim - 1 else a


def check_experiment(
    P,
    noise_cov,
    *,
    components: Sequence[str],
    state_units: Sequence[str],
    measurement_units: Sequence[str],
    reference: Mapping[str, float] | None = None,
    mode: Mode = "matched",
    orders: float = ORDERS,
    burn_in: int = BURN_IN,
    fraction: float = FRACTION,
    culprits: Sequence[str] = (),
    observation=None,
    channels: Sequence[str] | None = None,
    first_step: int = 1,
) -> ExperimentQuality:
    """R16 on the a-posteriori covariances P(k|k) ((K,) n × n) for k = first_step, ….

    ``noise_cov`` is V_η(k) ((K,) m × m).  ``reference`` maps component names to user reference
    variances r_i (matched mode).  ``culprits`` are parameter names from R5/R7 (see
    :func:`culprits_of`); ``observation`` H ((K,) m × n) with ``channels`` names the channels that act
    on the flagged components (H_li ≠ 0 at some considered step).
    """
    if mode not in ("matched", "literal"):
        raise ValueError(f"mode must be 'matched' or 'literal', not {mode!r}")
    if not 0.0 < fraction <= 1.0:
        raise ValueError("fraction must be in (0, 1]")
    P = _batch(P, 3)
    K, n, _ = P.shape
    cov = np.broadcast_to(_batch(noise_cov, 3), (K, *np.shape(noise_cov)[-2:]))
    components = tuple(components)
    if len(components) != n or len(state_units) != n:
        raise ValueError(f"{len(components)} names and {len(state_units)} units for {n} components")
    if len(measurement_units) != cov.shape[-1]:
        raise ValueError(f"{len(measurement_units)} units for {cov.shape[-1]} measurement channels")
    variances = np.diagonal(P, axis1=-2, axis2=-1)
    channel_variances = np.diagonal(cov, axis1=-2, axis2=-1)
    largest_channel = channel_variances.max(axis=-1)
    literal_ratio = np.abs(P).max(axis=(-2, -1)) / largest_channel
    threshold = 10.0**orders

    if mode == "literal":
        ref = np.broadcast_to(largest_channel[:, None], (K, n)).copy()
    else:
        ref = np.full((K, n), np.nan)
        units = np.asarray(measurement_units)
        for i, unit in enumerate(state_units):
            same = units == unit
            if same.any():
                ref[:, i] = channel_variances[:, same].min(axis=-1)
        for name, value in (reference or {}).items():
            ref[:, components.index(name)] = float(value)
    with np.errstate(invalid="ignore"):
        component_ratio = variances / ref
        flagged_components = component_ratio >= threshold
    flagged_steps = flagged_components.any(axis=1)
    steps = np.arange(first_step, first_step + K)
    considered = steps > burn_in
    if not considered.any():
        considered = steps == steps[-1]
    poorly = flagged_steps[considered].mean() >= fraction

    advice = None
    if poorly:
        flagged = flagged_components[considered].any(axis=0)
        names = [name for name, f in zip(components, flagged) if f]
        acting: list[str] = []
        if observation is not None:
            H = np.broadcast_to(_batch(observation, 3), (K, cov.shape[-1], n))[considered]
            acts = (H[:, :, flagged] != 0).any(axis=(0, 2))
            labels = channels if channels is not None else [f"y{l + 1}" for l in range(len(acts))]
            acting = [label for label, a in zip(labels, acts) if a]
        advice = advice_text(names, orders, culprits, acting)

    return ExperimentQuality(
        mode=mode,
        orders=orders,
        burn_in=burn_in,
        fraction=fraction,
        components=components,
        steps=steps,
        literal_ratio=literal_ratio,
        reference=ref,
        component_ratio=component_ratio,
        flagged_components=flagged_components,
        flagged_steps=flagged_steps,
        considered=considered,
        advice=advice,
    )


def covariance_recursion(F, V_w, h_a, H, noise_cov, P0, steps: int, Q_dep=None) -> np.ndarray:
    """P(k|k), k = 1 … steps, of the linear Kalman filter with fixed V_w (TV12 b, E6).

    V_x(k|k-1) = F P F ᵀ + Q_dep + G V_w Gᵀ with G = F h_aᵀ (eqs. 3-4), gain (6) by a Cholesky
    solve, Joseph update.  ``F``, ``H``, ``noise_cov`` constant; returns (steps, n, n).
    """
    F, H, R = (np.asarray(a, dtype=float) for a in (F, H, noise_cov))
    G = F @ np.asarray(h_a, dtype=float).T
    Q = G @ np.asarray(V_w, dtype=float) @ G.T
    if Q_dep is not None:
        Q = Q + np.asarray(Q_dep, dtype=float)
    P = np.asarray(P0, dtype=float)
    identity = np.eye(len(P))
    out = np.empty((steps, *P.shape))
    for k in range(steps):  # a recursion: each step needs the previous one
        predicted = F @ P @ F.T + Q
        innovation = H @ predicted @ H.T + R
        gain = np.linalg.solve(innovation, H @ predicted).T
        reduce = identity - gain @ H
        P = reduce @ predicted @ reduce.T + gain @ R @ gain.T
        out[k] = 0.5 * (P + P.T)
    return out
