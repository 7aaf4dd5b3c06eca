"""Tracker configuration: motion model, gating, track management and geometry defaults."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from skytrack.models.motion import MotionModel, constant_velocity, singer

MOTION_MODELS = ("singer", "cv")
INIT_METHODS = ("one-point", "two-point")
#: manoeuvre process-noise factor by model when none is given: the quiet CV model needs the
#: switch to follow turns; Singer's own acceleration state covers them (1 = switch off)
DEFAULT_MANOEUVRE_SCALE = {"cv": 3000.0, "singer": 1.0}


@dataclass
class TrackerConfig:
    """All tracker settings, with defaults suited to en-route surveillance radars.

    Motion model: ``model`` is ``"cv"`` (white-noise acceleration of PSD ``cv_q``, the
    default) or ``"singer"`` (per-axis Singer, spec 000; ``singer_tau_s``,
    ``singer_sigma_a``, ``discretization`` "exact" by default as spec 000 R2 asks for
    varying step lengths).  The defaults (quiet CV plus the manoeuvre switch below) were
    chosen on simulated en-route traffic with 2-3 g turns seen by a 4 s radar; see
    ``docs/tracker.md`` for the measured comparison with Singer.

    Gating: ``p_gate`` is the gate probability P_G; the threshold is the chi-square
    quantile for the number of measured components (spec 000 R7), or ``gate_threshold``
    when given.

    Management: a tentative track is confirmed when ``confirm_m`` of its last
    ``confirm_n`` expected observations were hits, and dropped as soon as that cannot
    happen any more; a confirmed track is deleted after ``delete_misses`` consecutive
    misses or when its position standard deviation exceeds ``max_position_sigma_m``.

    Initialisation: ``"one-point"`` starts from one plot with zero velocity and a velocity
    prior of ``init_sigma_v`` per axis; ``"two-point"`` does the same but replaces the state
    after the second plot by the two-point difference (position of the second plot,
    velocity from the difference, covariances from both plots' noise).

    Manoeuvre switch (spec 000 S3, the indicator psi): every track carries a flag psi.
    While psi = 0 the process noise is the model's; while psi = 1 it is multiplied by
    ``manoeuvre_q_scale``.  psi is set when the exponentially smoothed normalised
    innovation squared (NIS per component, smoothing weight ``manoeuvre_memory`` on the
    past) exceeds ``manoeuvre_on_nis`` and cleared when it falls below
    ``manoeuvre_off_nis``; ``manoeuvre_q_scale = 1`` switches the mechanism off, and
    ``None`` (the default) takes 3000 for CV and 1 (off) for Singer.  The flag
    is a function of past innovations only, as Theorem 1 (2a) requires.

    Geometry: ``tracking_dim`` 2 tracks in the horizontal plane (2-D radars, slant range
    projected with the Mode C altitude or ``default_altitude_m``), 3 in space; ``None``
    picks 3 when every radar is 3-D and 2 otherwise.
    """

    model: str = "cv"
    singer_tau_s: float = 20.0
    singer_sigma_a: float = 4.0
    discretization: str = "exact"
    cv_q: float = 0.5
    manoeuvre_q_scale: float | None = None
    manoeuvre_on_nis: float = 3.0
    manoeuvre_off_nis: float = 1.2
    manoeuvre_memory: float = 0.5
    p_gate: float = 0.9995
    gate_threshold: float | None = None
    confirm_m: int = 3
    confirm_n: int = 4
    delete_misses: int = 5
    max_position_sigma_m: float = 5000.0
    init: str = "one-point"
    init_sigma_v: float = 150.0
    tracking_dim: int | None = None
    default_altitude_m: float = 6000.0
    default_altitude_sigma_m: float = 3000.0
    mode_c_sigma_m: float = 30.0
    use_range_rate: bool = True
    sectors_per_scan: int | None = None
    window_s: float = 1.0
    output_interval_s: float | None = None
    full_covariance: bool = False
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.model not in MOTION_MODELS:
            raise ValueError(f"model must be one of {MOTION_MODELS}, got {self.model!r}")
        if self.init not in INIT_METHODS:
            raise ValueError(f"init must be one of {INIT_METHODS}, got {self.init!r}")
        if self.discretization not in ("paper", "exact"):
            raise ValueError(f"discretization must be 'paper' or 'exact', got {self.discretization!r}")
        if not 0.0 < self.p_gate < 1.0:
            raise ValueError(f"p_gate must be in (0, 1), got {self.p_gate}")
        if self.gate_threshold is not None and not self.gate_threshold > 0:
            raise ValueError(f"gate_threshold must be > 0, got {self.gate_threshold}")
        if not (1 <= self.confirm_m <= self.confirm_n <= 32):
            raise ValueError(f"need 1 <= confirm_m <= confirm_n <= 32, got {self.confirm_m}/{self.confirm_n}")
        if self.delete_misses < 1:
            raise ValueError(f"delete_misses must be >= 1, got {self.delete_misses}")
        if self.tracking_dim not in (None, 2, 3):
            raise ValueError(f"tracking_dim must be 2, 3 or None, got {self.tracking_dim}")
        for name in ("singer_tau_s", "init_sigma_v", "max_position_sigma_m", "default_altitude_sigma_m",
                     "mode_c_sigma_m", "window_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        for name in ("singer_sigma_a", "cv_q"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if self.manoeuvre_q_scale is not None and not (
            math.isfinite(self.manoeuvre_q_scale) and self.manoeuvre_q_scale >= 1.0
        ):
            raise ValueError(f"manoeuvre_q_scale must be >= 1, got {self.manoeuvre_q_scale}")
        if not 0.0 <= self.manoeuvre_memory < 1.0:
            raise ValueError(f"manoeuvre_memory must be in [0, 1), got {self.manoeuvre_memory}")
        if not 0.0 < self.manoeuvre_off_nis <= self.manoeuvre_on_nis:
            raise ValueError("need 0 < manoeuvre_off_nis <= manoeuvre_on_nis")
        if self.sectors_per_scan is not None and self.sectors_per_scan < 1:
            raise ValueError(f"sectors_per_scan must be >= 1, got {self.sectors_per_scan}")
        if self.output_interval_s is not None and not self.output_interval_s > 0:
            raise ValueError(f"output_interval_s must be > 0, got {self.output_interval_s}")

    @property
    def manoeuvre_scale(self) -> float:
        """The process-noise factor in use while psi = 1 (``manoeuvre_q_scale`` or the model's default)."""
        if self.manoeuvre_q_scale is not None:
            return self.manoeuvre_q_scale
        return DEFAULT_MANOEUVRE_SCALE[self.model]

    def motion_model(self, ndim: int) -> MotionModel:
        if self.model == "singer":
            return singer(ndim, self.singer_tau_s, self.singer_sigma_a, self.discretization)
        return constant_velocity(ndim, self.cv_q)

    def to_dict(self) -> dict:
        return asdict(self)
