"""The manoeuvre indicator psi of (S3) as a coefficient switch (spec 000, R10).

What lives here: :class:`ManeuverSwitch`, which maps a known per-scan psi in {0, 1} to
:class:`~skytrack.filters.spec000.params.SingerParams` (sigma_a = sigma_a(psi),
rho = rho(psi), §3.6 S3) and turns a psi sequence into a non-anticipative
``coefficient_policy`` (R10; Theorem 1 holds with past-dependent coefficients by (2a)).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from skytrack.filters.spec000.params import SingerHistory, SingerParams


class ManeuverSwitch:
    """Maps a known manoeuvre indicator psi in {0, 1} to Singer coefficients (spec 000, S3).

    ``switch(psi)`` gives the parameters; :meth:`policy` turns a per-scan psi sequence into
    a non-anticipative ``coefficient_policy``: before the step to scan n+1 it is called with
    the history of scans 0..n and returns the parameters for psi[n+1] (scans counted from 1,
    psi[0] belongs to scan 1).
    """

    def __init__(self, params_quiet: SingerParams, params_manoeuvre: SingerParams):
        for name, p in (("params_quiet", params_quiet), ("params_manoeuvre", params_manoeuvre)):
            if not isinstance(p, SingerParams):
                raise TypeError(f"ManeuverSwitch.{name} must be SingerParams, got {type(p).__name__}")
        self.params_quiet = params_quiet
        self.params_manoeuvre = params_manoeuvre

    def __call__(self, psi) -> SingerParams:
        if psi in (0, False):
            return self.params_quiet
        if psi in (1, True):
            return self.params_manoeuvre
        raise ValueError(f"manoeuvre indicator psi must be 0 or 1, got {psi!r}")

    def policy(self, psi_per_scan: Sequence[int]) -> Callable[["SingerHistory"], SingerParams]:
        schedule = [self(p) for p in psi_per_scan]

        def coefficient_policy(history: SingerHistory) -> SingerParams:
            step = len(history)
            if step >= len(schedule):
                raise ValueError(f"manoeuvre schedule has {len(schedule)} scans; step {step + 1} requested")
            return schedule[step]

        return coefficient_policy
