"""Static multiple-model bank with divergence switch-off (spec 004 §3.3 N, R16).

``M`` member filters (any family with a covariance, on one state space) run independently on
every measurement; nothing is mixed between them.  Per row:

* probabilities over the active members, in the log domain:
  ``mu_j(k) = L_j(k) mu_j(k-1) / sum_i L_i(k) mu_i(k-1)``;
* output: the moment-matched ``x = sum mu_j x_j``, ``P = sum mu_j [P_j + (x_j - x)(x_j - x)^T]``
  (``output="mixture"``, default) or the most probable member (``output="map"``); gating uses
  the moment-matched prediction with the weights ``mu(k-1)`` (R20);
* divergence test per active member once ``W + 5`` scans have been processed:
  ``sum over the last W scans of eps_j > chi2_{n_z W}^-1(1 - P_div)`` switches the member off,
  never the last active one (if every active member fails, the one with the smallest sum stays);
* ``switch_off="permanent"`` with ``mu_floor=0`` is the literal method (a floor may be added);
  the default (``"reenable"``, which needs ``mu_floor > 0``) floors active probabilities at
  ``mu_floor`` (renormalised), never switches
  off the most probable member, and, ``cooldown`` scans after a switch-off, re-initialises the
  member from the bank output with ``mu = mu_floor``.  The test's false-alarm rate is
  ``P_div`` per member and scan, so over hundreds of scans the literal rule does switch off a
  well-matched member now and then, leaving the bank on a wrong model until it is re-enabled;
  protecting the most probable member avoids that.

The state type is built per member list (:func:`bank_state_type`): a dataclass whose array
fields are each member's fields prefixed ``m<j>_`` plus the bank's own arrays, so rows can
be taken, put, concatenated and saved like any other state.  Switch-offs and re-enables go to
the recorder channels ``"switch_off"`` and ``"reenable"`` (rows, member, scan) and the
probabilities to ``"model_probabilities"``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.special import logsumexp

from skytrack.core.chi2 import chi2_quantile
from skytrack.core import linalg
from skytrack.filters.base import ArrayState, BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, _names
from skytrack.filters.imm import posterior_probabilities
from skytrack.filters.kalman import innovate_gaussian

SWITCH_OFF_MODES = ("permanent", "reenable")
OUTPUTS = ("mixture", "map")
#: bank arrays kept next to the members' (names must not start with "m<digit>_")
BANK_FIELDS = ("mu", "active", "eps_window", "scans", "off_scans")


class BankStateBase(ArrayState):
    """Methods shared by the generated bank state types (see :func:`bank_state_type`)."""

    member_types: tuple[type[ArrayState], ...] = ()
    map_output: bool = False

    def member(self, j: int) -> ArrayState:
        kind = self.member_types[j]
        return kind(*[getattr(self, f"m{j}_{name}") for name in _names(kind)])

    def members(self) -> list[ArrayState]:
        return [self.member(j) for j in range(len(self.member_types))]

    @classmethod
    def assemble(cls, members: list[ArrayState], **bank: np.ndarray) -> "BankStateBase":
        values = {f"m{j}_{name}": getattr(state, name) for j, state in enumerate(members) for name in _names(type(state))}
        values.update(bank)
        return cls(**values)

    def member_estimates(self) -> tuple[np.ndarray, np.ndarray]:
        estimates = [m.estimate() for m in self.members()]
        return np.stack([e.x for e in estimates], axis=1), np.stack([e.P for e in estimates], axis=1)

    def estimate(self) -> GaussianState:
        """The bank's output: the moment-matched mixture, or the most probable member's estimate."""
        xs, Ps = self.member_estimates()
        if self.map_output:
            best = np.argmax(self.mu, axis=1)
            rows = np.arange(len(self.mu))
            return GaussianState(xs[rows, best], Ps[rows, best])
        return moment_match(xs, Ps, self.mu)


@lru_cache(maxsize=None)
def bank_state_type(member_types: tuple[type[ArrayState], ...], map_output: bool = False) -> type[BankStateBase]:
    """The state dataclass of a bank over members with these state types (and this output rule)."""
    fields = [(f"m{j}_{name}", np.ndarray) for j, kind in enumerate(member_types) for name in _names(kind)]
    fields += [(name, np.ndarray) for name in BANK_FIELDS]
    name = "BankState_" + "_".join(kind.__name__ for kind in member_types) + ("_map" if map_output else "")
    cls = dataclasses.make_dataclass(name, fields, bases=(BankStateBase,),
                                     namespace={"member_types": member_types, "map_output": map_output})
    cls.__module__ = __name__
    return cls


def moment_match(xs: np.ndarray, Ps: np.ndarray, mu: np.ndarray) -> GaussianState:
    """``x = sum mu_j x_j``, ``P = sum mu_j [P_j + (x_j - x)(x_j - x)^T]`` over axis 1."""
    x = np.einsum("km,kmi->ki", mu, xs)
    d = xs - x[:, None, :]
    P = np.einsum("km,kmij->kij", mu, Ps + d[..., :, None] * d[..., None, :])
    return GaussianState(x, linalg.symmetrize(P))


@dataclass(eq=False)
class StaticBankFilter(BatchFilter):
    """Parallel filters without mixing, with divergence switch-off (spec 004 §3.3 N)."""

    members: list[BatchFilter]
    window: int = 5
    p_divergence: float = 0.001
    switch_off: str = "reenable"
    mu_floor: float = 1e-3
    cooldown: int = 20
    output: str = "mixture"
    initial_probabilities: np.ndarray | None = None
    names: tuple[str, ...] | None = None
    state_type: type = field(init=False)

    kind = "static-bank"
    capabilities = Capabilities(multiple_model=True)

    def __post_init__(self) -> None:
        count = len(self.members)
        if count < 1:
            raise ValueError("a static bank needs at least one member filter")
        if any(not m.capabilities.has_covariance for m in self.members):
            raise ValueError("static bank members must have a covariance (spec 004 §3.3 N)")
        if len({m.state_dim for m in self.members}) != 1:
            raise ValueError(f"bank members must share one state space, got dimensions {[m.state_dim for m in self.members]}")
        if not (isinstance(self.window, (int, np.integer)) and self.window >= 1):
            raise ValueError(f"static bank: window must be an integer >= 1, got {self.window}")
        if not 0.0 < self.p_divergence < 1.0:
            raise ValueError(f"static bank: p_divergence must be in (0, 1), got {self.p_divergence}")
        if self.switch_off not in SWITCH_OFF_MODES:
            raise ValueError(f"static bank: switch_off must be one of {SWITCH_OFF_MODES}, got {self.switch_off!r}")
        if not 0.0 <= self.mu_floor < 1.0 / count:
            raise ValueError(f"static bank: mu_floor must be in [0, 1/{count}), got {self.mu_floor}")
        if self.switch_off == "reenable" and self.mu_floor == 0.0:
            raise ValueError("static bank: switch_off='reenable' needs mu_floor > 0 (a member re-enabled with "
                             "probability 0 could never regain weight)")
        if not (isinstance(self.cooldown, (int, np.integer)) and self.cooldown >= 1):
            raise ValueError(f"static bank: cooldown must be an integer >= 1, got {self.cooldown}")
        if self.output not in OUTPUTS:
            raise ValueError(f"static bank: output must be one of {OUTPUTS}, got {self.output!r}")
        if self.initial_probabilities is None:
            self.initial_probabilities = np.full(count, 1.0 / count)
        self.initial_probabilities = np.asarray(self.initial_probabilities, dtype=float)
        if self.initial_probabilities.shape != (count,) or not np.isclose(self.initial_probabilities.sum(), 1.0):
            raise ValueError(f"static bank: initial_probabilities must be {count} probabilities summing to 1")
        self.names = tuple(self.names) if self.names is not None else tuple(f"member{j}" for j in range(count))
        self.state_type = bank_state_type(tuple(m.state_type for m in self.members), self.output == "map")

    @property
    def state_dim(self) -> int:
        return self.members[0].state_dim

    @property
    def n_members(self) -> int:
        return len(self.members)

    def divergence_threshold(self, n_z: np.ndarray) -> np.ndarray:
        """``chi2_{n_z W}^-1(1 - P_div)`` per row."""
        return chi2_quantile(1.0 - self.p_divergence, np.asarray(n_z) * self.window)

    def initiate(self, x: np.ndarray, P: np.ndarray) -> BankStateBase:
        rows, count = len(x), self.n_members
        return self.state_type.assemble(
            [m.initiate(x, P) for m in self.members], mu=np.tile(self.initial_probabilities, (rows, 1)),
            active=np.ones((rows, count), bool), eps_window=np.zeros((rows, count, self.window)),
            scans=np.zeros(rows, np.int64), off_scans=np.zeros((rows, count), np.int64))

    def _bank_arrays(self, state: BankStateBase, **changes) -> dict[str, np.ndarray]:
        arrays = {name: getattr(state, name) for name in BANK_FIELDS}
        arrays.update(changes)
        return arrays

    def predict(self, state: BankStateBase, dt, context: dict | None = None) -> BankStateBase:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        members = [m.predict(s, dt, context) for m, s in zip(self.members, state.members())]
        return self.state_type.assemble(members, **self._bank_arrays(state))

    def innovate(self, state: BankStateBase, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        per_member = [m.innovate(s, z, model, context) for m, s in zip(self.members, state.members())]
        member_loglik = np.stack([inn.loglik for inn in per_member], axis=1)
        combined = innovate_gaussian(state.estimate(), z, model, context)
        combined.loglik = logsumexp(member_loglik, axis=1, b=state.mu)
        combined.predicted = state
        combined.extra["members"] = per_member
        combined.extra["member_loglik"] = member_loglik
        combined.extra["member_d2"] = np.stack([inn.d2 for inn in per_member], axis=1)
        return combined

    def update(self, state: BankStateBase, z: np.ndarray, innovation: Innovation) -> tuple[BankStateBase, UpdateStats]:
        predicted: BankStateBase = innovation.predicted
        rows = len(predicted)
        members = [m.update(s, z, inn)[0] for m, s, inn in
                   zip(self.members, predicted.members(), innovation.extra["members"])]
        active = predicted.active.copy()
        prior = np.where(active, predicted.mu, 0.0)
        mu = posterior_probabilities(prior, innovation.extra["member_loglik"])
        eps_window = np.concatenate([predicted.eps_window[:, :, 1:], innovation.extra["member_d2"][:, :, None]], axis=2)
        scans = predicted.scans + 1
        off_scans = np.where(active, 0, predicted.off_scans + 1)

        # divergence test
        tested = (scans >= self.window + 5)[:, None] & active
        sums = eps_window.sum(axis=2)
        diverged = tested & (sums > self.divergence_threshold(innovation.m)[:, None])
        if self.switch_off == "reenable":
            diverged[np.arange(rows), np.argmax(mu, axis=1)] = False
        left = active & ~diverged
        none_left = ~left.any(axis=1)
        if none_left.any():  # never switch off the last active member: keep the least divergent
            keep = np.argmin(np.where(active, sums, np.inf), axis=1)
            diverged[none_left, keep[none_left]] = False
        if diverged.any():
            r, j = np.nonzero(diverged)
            self.recorder.record("switch_off", r, member=j, scan=scans[r])
            active &= ~diverged
            off_scans[diverged] = 0
        mu = np.where(active, mu, 0.0)
        mu /= mu.sum(axis=1, keepdims=True)

        if self.switch_off == "reenable":
            due = ~active & (off_scans >= self.cooldown)
            if due.any():
                output = self.state_type.assemble(members, **self._bank_arrays(predicted, mu=mu)).estimate()
                for j in np.flatnonzero(due.any(axis=0)):
                    which = np.flatnonzero(due[:, j])
                    members[j].put(which, self.members[j].initiate(output.x[which], output.P[which]))
                    eps_window[which, j] = 0.0
                    mu[which, j] = self.mu_floor
                active |= due
                r, j = np.nonzero(due)
                self.recorder.record("reenable", r, member=j, scan=scans[r])
                mu /= mu.sum(axis=1, keepdims=True)

        if self.mu_floor > 0.0:  # in either switch-off mode
            mu = floored(mu, active, self.mu_floor)
        if self.recorder.active:
            self.recorder.record("model_probabilities", np.arange(rows), mu=mu)
        new = self.state_type.assemble(members, mu=mu, active=active, eps_window=eps_window, scans=scans,
                                       off_scans=off_scans)
        return new, UpdateStats(innovation.d2 / innovation.m)


def floored(mu: np.ndarray, active: np.ndarray, floor: float) -> np.ndarray:
    """Active probabilities raised to at least ``floor`` with the rest scaled to keep the sum 1."""
    low = active & (mu < floor)
    if not low.any():
        return mu
    lifted = low.sum(axis=1, keepdims=True) * floor
    rest = np.where(active & ~low, mu, 0.0)
    scale = (1.0 - lifted) / np.maximum(rest.sum(axis=1, keepdims=True), 1e-300)
    return np.where(low, floor, rest * scale)
