"""Argument checks shared by the spec 000 filters (R2, R3, R16: parameters, dt and input are validated).

What lives here: the measurement variants of the paper (:data:`MEASUREMENT_INDEX`, the
measured state rows of (M2) "pos" and (M3) "posvel") and the private checks of dt, standard
deviations, measurement variant, update form (R3: "joseph" or "standard") and covariances
(finite, symmetric, positive semi-definite, R16).  No equations.
"""

from __future__ import annotations

import math

import numpy as np

from skytrack.filters.ekf import UPDATE_FORMS

#: measurement variants of the paper: measured state indices per variant (M2, M3)
MEASUREMENT_INDEX: dict[str, tuple[int, ...]] = {"pos": (0,), "posvel": (0, 1)}


def _check_dt(dt) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a number of seconds, got {dt!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    return value


def _check_sigma(name: str, value) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return arr


def _check_measurement(measurement: str) -> tuple[int, ...]:
    if measurement not in MEASUREMENT_INDEX:
        raise ValueError(f"measurement must be one of {tuple(MEASUREMENT_INDEX)}, got {measurement!r}")
    return MEASUREMENT_INDEX[measurement]


def _check_form(update_form: str) -> str:
    if update_form not in UPDATE_FORMS:
        raise ValueError(f"update_form must be one of {UPDATE_FORMS}, got {update_form!r}")
    return update_form


def _check_covariance(name: str, P: np.ndarray) -> None:
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{name} contains non-finite values")
    if np.max(np.abs(P - np.swapaxes(P, -1, -2)), initial=0.0) > 1e-9 * max(np.max(np.abs(P)), 1e-300):
        raise ValueError(f"{name} is not symmetric")
    if np.any(np.linalg.eigvalsh(P)[..., 0] < -1e-9 * np.max(np.abs(P))):
        raise ValueError(f"{name} is not positive semi-definite")
