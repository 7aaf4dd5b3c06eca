"""The filter catalogue of the studies: labelled filter specifications (spec 004 §6 default parameters).

A :class:`FilterSpec` names a registered filter kind (:mod:`skytrack.filters.registry`), the
motion model it runs on (a small dict, so configuration files can add filters) and the
factory options.  Options that depend on the scenario are *derived* at build time from the
:class:`FilterSetting` (scan period, initial measurement covariance): a spec lists their names
in ``derived`` and :data:`DERIVED` computes them.

Motion dicts (3-D, axis-major layout of spec 004 §2)::

    {model: dwna, sigma_w: 1}        # piecewise-constant white acceleration (order 2)
    {model: dwpa, sigma_w: 8}        # white acceleration increment (order 3)
    {model: cv, q: 1}                # continuous white acceleration, PSD q (order 2)
    {model: ca, q: 1}                # continuous white jerk, PSD q (order 3)
    {model: singer, tau: 10, sigma_m: 30}
    {model: polynomial, order: 3, noise: continuous, intensity: 1}
    {model: dwna, sigma_w: 1, embed: 3}   # any model embedded in 3 states per axis (multiple-model filters)

The catalogue :data:`CATALOG` holds the §6 table entries that exist in the filter registry;
studies pick labels from it (``--filters``) and a ``--config`` file's ``filters`` section adds or
overrides entries (``label: {kind, motion, options, derived, r_scale, description}``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from skytrack.filters.base import BatchFilter
from skytrack.models.polynomial import dwna, dwpa, polynomial
from skytrack.models.embedding import embed
from skytrack.models.motion import MotionModel, constant_acceleration, constant_velocity, singer

NDIM = 3
MOTION_KEYS = {
    "dwna": {"sigma_w"},
    "dwpa": {"sigma_w"},
    "cv": {"q"},
    "ca": {"q"},
    "singer": {"tau", "sigma_m"},
    "polynomial": {"order", "noise", "intensity"},
}


def build_motion(spec: dict) -> MotionModel:
    """The 3-D :class:`MotionModel` of a motion dict (module docstring)."""
    motion = _base_motion(spec)
    if spec.get("embed") is not None:
        motion = embed(motion, int(spec["embed"]))
    return motion


def _base_motion(spec: dict) -> MotionModel:
    if not isinstance(spec, dict) or "model" not in spec:
        raise ValueError(f"filter motion must be a mapping with a 'model' key, got {spec!r}")
    model = spec["model"]
    if model not in MOTION_KEYS:
        raise ValueError(f"filter motion: unknown model {model!r}; known: {', '.join(MOTION_KEYS)}")
    params = {k: v for k, v in spec.items() if k not in ("model", "embed")}
    unknown = sorted(set(params) - MOTION_KEYS[model])
    if unknown:
        raise ValueError(f"filter motion {model!r}: unknown key(s) {unknown}; known: {sorted(MOTION_KEYS[model])}")
    if model == "cv":
        return constant_velocity(NDIM, float(params.get("q", 1.0)))
    if model == "ca":
        return constant_acceleration(NDIM, float(params.get("q", 1.0)))
    if model == "singer":
        return singer(NDIM, float(params.get("tau", 10.0)), float(params.get("sigma_m", 30.0)), "exact")
    if model == "dwna":
        return dwna(NDIM, float(params.get("sigma_w", 1.0)))
    if model == "dwpa":
        return dwpa(NDIM, float(params.get("sigma_w", 1.0)))
    return polynomial(NDIM, int(params.get("order", 2)), str(params.get("noise", "continuous")),
                                 float(params.get("intensity", 0.0)))


@dataclass(frozen=True)
class FilterSetting:
    """What a filter may be tuned to at build time: scan period and the first measurement covariances."""

    dt: float
    R0: np.ndarray  # [runs, 3, 3] covariance of the first measurement of every run
    sensor_position: tuple[float, float, float] = (0.0, 0.0, 0.0)


def sigma_v_per_axis(setting: FilterSetting) -> np.ndarray:
    """sigma_v of constant-gain filters per axis: root mean over runs of the first R's diagonal (§6 table)."""
    return np.sqrt(np.mean(np.diagonal(setting.R0, axis1=-2, axis2=-1), axis=0))


def _tracking_index(setting: FilterSetting, design: dict):
    """Kalata tracking index ``sigma_w T^2 / sigma_v`` per axis from ``design["sigma_w"]`` (and
    ``design["sigma_v"]``, default :func:`sigma_v_per_axis`)."""
    if "sigma_w" not in design:
        raise ValueError("the derived option tracking_index needs design.sigma_w")
    sigma_v = np.asarray(design.get("sigma_v", sigma_v_per_axis(setting)), dtype=float)
    index = float(design["sigma_w"]) * setting.dt**2 / sigma_v
    return tuple(float(v) for v in np.broadcast_to(index, (NDIM,)))


#: derived option name -> its value for a setting and the spec's design parameters
DERIVED: dict[str, Callable[[FilterSetting, dict], object]] = {
    "sigma_v": lambda setting, design: tuple(float(v) for v in sigma_v_per_axis(setting)),
    "dt": lambda setting, design: float(setting.dt),
    "period": lambda setting, design: float(setting.dt),
    "sensor_position": lambda setting, design: tuple(float(v) for v in setting.sensor_position),
    "tracking_index": _tracking_index,
}


@dataclass(frozen=True)
class FilterSpec:
    """A labelled filter: registry ``kind``, ``motion`` dict, factory ``options`` and derived options.

    ``derived`` names options computed at build time (:data:`DERIVED`) from the setting and the
    ``design`` parameters (which are not passed to the factory), e.g. the Kalata tracking index
    from ``design = {"sigma_w": 10}`` and the first measurement covariance.

    ``r_scale`` multiplies the measurement covariance handed to the filter; ``initiation`` is the
    runner's start (``two-point``, or ``two-point-set`` for set-membership filters);
    ``description`` is the figure/summary text.
    """

    label: str
    kind: str
    motion: dict
    options: dict = field(default_factory=dict)
    derived: tuple[str, ...] = ()
    r_scale: float = 1.0
    description: str = ""
    design: dict = field(default_factory=dict)
    initiation: str = "two-point"

    def __post_init__(self) -> None:
        unknown = [name for name in self.derived if name not in DERIVED]
        if unknown:
            raise ValueError(f"filter {self.label!r}: unknown derived option(s) {unknown}; known: {sorted(DERIVED)}")
        if not (math.isfinite(self.r_scale) and self.r_scale > 0):
            raise ValueError(f"filter {self.label!r}: r_scale must be > 0, got {self.r_scale}")
        if self.initiation not in ("two-point", "two-point-set"):
            raise ValueError(f"filter {self.label!r}: initiation must be two-point or two-point-set, got {self.initiation!r}")

    def build(self, setting: FilterSetting) -> tuple[BatchFilter, MotionModel]:
        """The filter (through :func:`skytrack.filters.registry.build_filter`) and its motion model."""
        from skytrack.filters.registry import build_filter

        motion = build_motion(self.motion)
        options = dict(self.options)
        for name in self.derived:
            options.setdefault(name, DERIVED[name](setting, self.design))
        try:
            return build_filter(self.kind, motion, **options), motion
        except ValueError as exc:
            raise ValueError(f"filter {self.label!r}: {exc}") from None

    @classmethod
    def from_dict(cls, label: str, values: dict) -> "FilterSpec":
        known = {"kind", "motion", "options", "derived", "r_scale", "description", "design", "initiation"}
        if not isinstance(values, dict):
            raise ValueError(f"filters.{label}: expected a mapping, got {values!r}")
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"filters.{label}: unknown key(s) {unknown}; known: {sorted(known)}")
        if "kind" not in values or "motion" not in values:
            raise ValueError(f"filters.{label}: needs kind and motion")
        spec = cls(label, str(values["kind"]), dict(values["motion"]), dict(values.get("options") or {}),
                   tuple(values.get("derived") or ()), float(values.get("r_scale", 1.0)), str(values.get("description", "")),
                   dict(values.get("design") or {}), str(values.get("initiation", "two-point")))
        build_motion(spec.motion)  # fail early on a bad motion
        return spec


def _spec(label, kind, motion, description, **extra) -> FilterSpec:
    return FilterSpec(label, kind, motion, description=description, **extra)


SINGER = {"model": "singer", "tau": 10.0, "sigma_m": 30.0}
CV = {"model": "dwna", "sigma_w": 1.0}
ORDER3 = {"model": "dwpa", "sigma_w": 8.0}  # families that use only the axes of their motion (3 states per axis)
#: §6's adaptive filter is §3.3 F's: the spec's weights d_k (weighting "fading"), not the filter's
#: default information weighting, whose prior around q0 = 25 would mostly keep q-hat there
ADAPTIVE = {"variant": "structured", "b": 0.97, "warmup": 10, "r0_scale": 4.0, "q0": 25.0, "weighting": "fading"}

#: §6 default filter parameters, one entry per row of the table (PCG for each N, IMM for each set)
CATALOG: dict[str, FilterSpec] = {s.label: s for s in (
    _spec("kf-cv", "kalman", CV, "KF-CV, DWNA sigma_w = 1 m/s^2"),
    _spec("pseudo-noise", "kalman-pseudo-noise", CV, "pseudo-noise KF-CV, constant q = 400: DWNA sigma_w = 20 m/s^2",
          options={"q": 400.0}),
    _spec("kf-ca", "kalman", {"model": "dwpa", "sigma_w": 8.0}, "KF-CA, DWPA sigma_w = 8 m/s^2"),
    _spec("kf-dwpa", "kalman", {"model": "dwpa", "sigma_w": 10.0}, "KF-DWPA, sigma_w = 10 m/s^2 (the alpha-beta-gamma's KF)"),
    _spec("kf-singer", "kalman", SINGER, "KF-Singer, tau = 10 s, sigma_m = 30 m/s^2"),
    _spec("alpha-beta", "alpha-beta", {"model": "dwna", "sigma_w": 5.0}, "alpha-beta, Kalata DWNA sigma_w = 5 m/s^2",
          options={"gain_rule": "kalata"}, derived=("tracking_index", "period"), design={"sigma_w": 5.0}),
    _spec("alpha-beta-gamma", "alpha-beta", {"model": "dwpa", "sigma_w": 10.0},
          "alpha-beta-gamma, Kalata DWPA sigma_w = 10 m/s^2", options={"gain_rule": "kalata"},
          derived=("tracking_index", "period"), design={"sigma_w": 10.0}),
    _spec("per-axis", "kalman-per-axis", SINGER, "per-axis KF, Singer 10 s, 30 m/s^2"),
    _spec("transformed-gain", "kalman-transformed-gain", SINGER, "transformed-gain KF (LOS frame), Singer 10 s, 30 m/s^2",
          derived=("sensor_position",)),
    *[_spec(f"pcg-{n}", "kalman-piecewise-gain", SINGER, f"piecewise-constant gain N = {n}, Singer 10 s, 30 m/s^2",
            options={"N": n}) for n in (1, 2, 5, 10, 20)],
    _spec("adaptive", "kalman-adaptive", CV, "adaptive KF (structured Sage-Husa), CV, R0 = 4 R, q0 = 25",
          options=dict(ADAPTIVE), derived=("period",)),
    _spec("set-membership", "set-membership", CV, "set-membership, CV, |a_i| <= 7 g0 box bound, R_b = 9 R",
          options={"r_bound_scale": 9.0}, initiation="two-point-set"),
    _spec("vd", "variable-dimension", ORDER3, "VD, sigma_cv = 1, sigma_ca = 8, rho = 0.8, P_fa = 0.01",
          options={"sigma_cv": 1.0, "sigma_ca": 8.0, "rho": 0.8, "p_fa": 0.01}),
    _spec("ie", "input-estimation", ORDER3, "input estimation, CV sigma_w = 1, N_w = 20, P_fa = 0.01, Bonferroni",
          options={"sigma_w": 1.0, "window": 20, "p_fa": 0.01, "bonferroni": True}),
    _spec("adaptive-ie", "adaptive-input-estimation", ORDER3, "structured adaptive KF + IE (N_w = 20, P_fa = 0.01)",
          options={"window": 20, "p_fa": 0.01, "bonferroni": True, "b": 0.97, "warmup": 10, "r0_scale": 4.0, "q0": 25.0,
                   "weighting": "fading"}),
    _spec("berg-full", "berg-full", ORDER3, "Berg full 9x9, (tau, sigma) = (60, 3), (15, 40), (30, 10), mean jerk",
          options={"tangential": (60.0, 3.0), "normal": (15.0, 40.0), "binormal": (30.0, 10.0), "mean_jerk": True}),
    _spec("berg-frame", "berg-frame", ORDER3, "Berg target-frame blocks, channels as berg-full, mean jerk",
          options={"tangential": (60.0, 3.0), "normal": (15.0, 40.0), "binormal": (30.0, 10.0), "mean_jerk": True}),
    _spec("static-bank", "static-bank", ORDER3, "static bank CV/CA/Singer, W = 5, P_div = 0.001, mu_min = 1e-3, cooldown 20",
          options={"model_set": "cv-ca-singer", "window": 5, "p_divergence": 0.001, "mu_floor": 1e-3, "cooldown": 20}),
    *[_spec(f"imm-{name}", "imm", ORDER3, f"IMM {name} (sojourn CV 20 s, others 10 s)", options={"model_set": name})
      for name in ("cv-ca", "cv-ct", "full")],
)}


def resolve_filters(labels, catalog: dict[str, FilterSpec]) -> list[FilterSpec]:
    """The specs of ``labels`` (unknown labels: a ValueError naming the known ones)."""
    out = []
    for label in labels:
        if label not in catalog:
            raise ValueError(f"--filters: unknown filter {label!r}; known: {', '.join(sorted(catalog))}")
        out.append(catalog[label])
    if len({s.label for s in out}) != len(out):
        raise ValueError(f"--filters: a filter is listed twice in {list(labels)}")
    return out
