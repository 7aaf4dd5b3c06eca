"""Named model sets of spec 004 (R18) and the registered multiple-model filters "imm" and "static-bank".

A model set is a list of named motion models on one state space, used by both the IMM
(:mod:`skytrack.filters.imm`, R17) and the static bank (:mod:`skytrack.filters.static_bank`, R16):

=============== ===================================================================== =========
set             modes                                                                 order
=============== ===================================================================== =========
``cv-ca``       CV (DWNA sigma_cv = 1 m/s^2), CA (DWPA sigma_ca = 8 m/s^2)              3
``cv-ct``       CV, CT(+omega0), CT(-omega0) (DWNA sigma_ct)                            2 or 3
``full``        CV, CA, CT(+omega0), CT(-omega0), Singer(tau 10 s, sigma_m 30 m/s^2)    3
``cv-ca-singer`` CV, CA, Singer: the static bank's default (``full`` minus CT, spec 004 §6) 3
``noise-levels`` the given motion model with its process noise times each of ``q_scales`` any
=============== ===================================================================== =========

``omega0 = n0 g0 / V0`` (spec defaults n0 = 5, V0 = 250 m/s, i.e. 0.196 rad/s) unless
``turn_rate_deg_s`` is given.  Order 3 is spec 004's m = 3 embedding (CV and CT padded with
zero accelerations, :mod:`skytrack.models.embedding`); order 2 is the tracker's
constant-velocity layout, where CV and CT share ``[x, vx, y, vy(, z, vz)]`` without an
acceleration state.  The state layout comes from the motion model the filter is built for.

Mode switching (IMM): mean sojourn times ``sojourn_s`` (default 20 s for CV, 10 s for every
other mode, spec 004 §6) give ``pi_jj = max(0, 1 - T/tau_j)`` per step; ``transition_matrix``
gives a fixed matrix instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.filters.imm import IMMFilter, SojournTransition, TransitionMatrix
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.registry import register_filter
from skytrack.filters.static_bank import StaticBankFilter
from skytrack.models.embedding import embed
from skytrack.models.motion import MotionModel, SingerAxisModel, constant_velocity
from skytrack.models.polynomial import dwna, dwpa
from skytrack.models.turn import coordinated_turn

G0 = 9.80665
MODEL_SETS = ("cv-ca", "cv-ct", "full", "cv-ca-singer", "noise-levels", "cv-ct-noisy")
#: sets that need the acceleration state of the m = 3 embedding
ORDER3_SETS = ("cv-ca", "full", "cv-ca-singer")
#: "dwna": the spec's discrete noise (sigma_cv, sigma_ct, m/s^2); "continuous": white acceleration
#: of PSD q_cv, q_ct (m^2/s^3) for CV and CT, right for a tracker's uneven revisit intervals
SET_NOISE = ("dwna", "continuous")


@dataclass(frozen=True)
class ModelSetParameters:
    """Parameters of the named sets (spec 004 R18 and §6 defaults; SI units)."""

    sigma_cv: float = 1.0
    sigma_ca: float = 8.0
    sigma_ct: float = 1.0
    load_factor: float = 5.0
    reference_speed: float = 250.0
    turn_rate_deg_s: float | None = None
    singer_tau: float = 10.0
    singer_sigma: float = 30.0
    q_scales: tuple[float, ...] = (1.0, 3000.0)
    noise: str = "dwna"
    q_cv: float = 0.5
    q_ct: float = 5.0
    noisy_factor: float = 3000.0

    def __post_init__(self) -> None:
        for name in ("sigma_cv", "sigma_ca", "sigma_ct", "load_factor", "reference_speed", "singer_tau", "singer_sigma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"model set: {name} must be finite and > 0, got {value}")
        if self.turn_rate_deg_s is not None and not (math.isfinite(self.turn_rate_deg_s) and self.turn_rate_deg_s > 0):
            raise ValueError(f"model set: turn_rate_deg_s must be finite and > 0, got {self.turn_rate_deg_s}")
        if self.noise not in SET_NOISE:
            raise ValueError(f"model set: noise must be one of {SET_NOISE}, got {self.noise!r}")
        for name in ("q_cv", "q_ct"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"model set: {name} must be finite and >= 0, got {value}")
        if len(self.q_scales) < 2 or any(not (math.isfinite(s) and s > 0) for s in self.q_scales):
            raise ValueError(f"model set: q_scales needs at least two finite factors > 0, got {self.q_scales}")

    @property
    def omega0(self) -> float:
        """Turn rate of the CT modes, rad/s: ``n0 g0 / V0`` or ``turn_rate_deg_s``."""
        if self.turn_rate_deg_s is not None:
            return math.radians(self.turn_rate_deg_s)
        return self.load_factor * G0 / self.reference_speed


def build_model_set(name: str, motion: MotionModel, params: ModelSetParameters | None = None) -> tuple[list[str], list]:
    """The named set's mode names and motion models in the layout of ``motion`` (its ndim and order)."""
    params = params or ModelSetParameters()
    if name not in MODEL_SETS:
        raise ValueError(f"unknown model set {name!r}; known: {', '.join(MODEL_SETS)}")
    ndim, order = motion.ndim, motion.order
    if name == "noise-levels":
        return [f"q x{scale:g}" for scale in params.q_scales], [motion.scaled(scale) for scale in params.q_scales]
    if name in ORDER3_SETS and order != 3:
        raise ValueError(f"model set {name!r} needs 3 states per axis (position, velocity, acceleration); "
                         f"the motion model has {order} (use a CA or Singer motion model: skytrack track --model singer)")
    if order not in (2, 3):
        raise ValueError(f"model set {name!r} needs 2 or 3 states per axis, the motion model has {order}")
    if "ct" in name.split("-") or name == "full":
        if ndim not in (2, 3):
            raise ValueError(f"model set {name!r}: a coordinated turn needs 2 or 3 axes, the motion model has {ndim}")

    continuous = params.noise == "continuous"

    def cv():
        return embed(constant_velocity(ndim, params.q_cv) if continuous else dwna(ndim, params.sigma_cv), order)

    def ct(sign):
        if continuous:
            return coordinated_turn(ndim, sign * params.omega0, math.sqrt(params.q_ct), order=order, noise="continuous")
        return coordinated_turn(ndim, sign * params.omega0, params.sigma_ct, order=order)

    def ca():
        return dwpa(ndim, params.sigma_ca)

    def singer():
        return MotionModel([SingerAxisModel(params.singer_tau, params.singer_sigma, "exact")] * ndim)

    turn = f"{math.degrees(params.omega0):.3g} deg/s"
    sets = {
        "cv-ca": [("CV", cv), ("CA", ca)],
        "cv-ct": [("CV", cv), (f"CT +{turn}", lambda: ct(1.0)), (f"CT -{turn}", lambda: ct(-1.0))],
        "full": [("CV", cv), ("CA", ca), (f"CT +{turn}", lambda: ct(1.0)), (f"CT -{turn}", lambda: ct(-1.0)),
                 ("Singer", singer)],
        "cv-ca-singer": [("CV", cv), ("CA", ca), ("Singer", singer)],
        "cv-ct-noisy": [("CV", cv), (f"CT +{turn}", lambda: ct(1.0)), (f"CT -{turn}", lambda: ct(-1.0)),
                        (f"CV q x{params.noisy_factor:g}", lambda: cv().scaled(params.noisy_factor))],
    }
    chosen = sets[name]
    return [label for label, _ in chosen], [build() for _, build in chosen]


def default_sojourn(count: int) -> tuple[float, ...]:
    """20 s in the first (quiet) mode, 10 s in every other (spec 004 §6)."""
    return (20.0,) + (10.0,) * (count - 1)


def _parameters(options: dict) -> ModelSetParameters:
    known = ModelSetParameters.__dataclass_fields__
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise TypeError(f"unexpected option(s) {', '.join(unknown)}")
    if "q_scales" in options:
        options = {**options, "q_scales": tuple(options["q_scales"])}
    return ModelSetParameters(**options)


def _default_set(motion: MotionModel, kind: str) -> str:
    return "cv-ct" if motion.order == 2 else ("cv-ca" if kind == "imm" else "cv-ca-singer")


@register_filter("imm")
def build_imm(motion: MotionModel, model_set: str | None = None, sojourn_s=None, transition_matrix=None,
              manoeuvre_gate: bool = True, compiled: bool = True, **set_options) -> IMMFilter:
    """IMM over a named model set (default ``cv-ct`` for 2 states per axis, ``cv-ca`` for 3)."""
    name = model_set or _default_set(motion, "imm")
    names, models = build_model_set(name, motion, _parameters(set_options))
    if sojourn_s is not None and transition_matrix is not None:
        raise ValueError("imm: give sojourn_s or transition_matrix, not both")
    if transition_matrix is not None:
        transition = TransitionMatrix(np.asarray(transition_matrix, dtype=float))
    else:
        transition = SojournTransition(tuple(sojourn_s) if sojourn_s is not None else default_sojourn(len(models)))
    return IMMFilter([KalmanFilter(m, compiled=compiled) for m in models], transition, names=tuple(names),
                     manoeuvre_mode=_noisiest_mode(name, set_options) if manoeuvre_gate else None,
                     compiled=compiled)


def _noisiest_mode(name: str, set_options: dict) -> int | None:
    """The mode a tracker's manoeuvre gate predicts with: the high-noise CV of the sets that have one."""
    if name == "noise-levels":
        return int(np.argmax(_parameters(set_options).q_scales))
    if name == "cv-ct-noisy":
        return 3
    return None


@register_filter("static-bank")
def build_static_bank(motion: MotionModel, model_set: str | None = None, window: int = 5,
                      p_divergence: float = 0.001, switch_off: str = "reenable", mu_floor: float = 1e-3,
                      cooldown: int = 20, output: str = "mixture", compiled: bool = True,
                      **set_options) -> StaticBankFilter:
    """Static bank of Kalman filters over a named model set (default ``cv-ca-singer`` for 3 states
    per axis as in spec 004 §6, ``cv-ct`` for 2)."""
    name = model_set or _default_set(motion, "static-bank")
    names, models = build_model_set(name, motion, _parameters(set_options))
    return StaticBankFilter([KalmanFilter(m, compiled=compiled) for m in models], window=window,
                            p_divergence=p_divergence, switch_off=switch_off, mu_floor=mu_floor, cooldown=cooldown,
                            output=output, names=tuple(names))
