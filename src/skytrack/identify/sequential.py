"""The optimal sequential pair test of spec 001: (14a), (17), (20), (20a), with R4-R6, R8, R15.

:class:`SequentialPairTest` holds, for a batch of K candidate pairs, three filters per pair
(:class:`~skytrack.identify.kalman.FilterBank` rows):

* the joint "same object" filter (θ = 1) over the merged, time-ordered stream ζ_k (14);
* the system-1 filter over η only (17), and the system-2 filter over ξ only (20).

After every report it exposes the four quadratic forms — Q_Jη and Q_Jξ, the joint filter's
increments at system-1 and system-2 reports, and Q_η, Q_ξ, the separate filters' sums —
the statistic Λ = Q_Jη + Q_Jξ − Q_η − Q_ξ of (20a) and its degrees of freedom
dof = r_η + r_ξ − r_J (R4, gap G7).  Λ is not monotone (TV-3b).

* :meth:`decide` is the Neyman–Pearson rule (20a) with the threshold modes of R5
  (:class:`~skytrack.identify.threshold.Threshold`): ``different`` if Λ > h, ``same`` if Λ ≤ h,
  ``insufficient`` while dof < dof_min.
* :meth:`log_odds` / :meth:`posterior` are R6 (gap G1): with the log-determinant terms D in
  prior mode, or the density form ln BF = −Λ/2 − ½ ln det(2π(P_η + P_ξ)) − ln β after a
  diffuse start.  ``include_logdet=False`` is the paper's literal (14a) with "constant" c: it
  is **not** a calibrated probability and warns so.
* ``statistic="joint-only"`` (R15) is this spec's reading of the quasi-optimal two-form
  algorithm of the paper's ref. [3] (gap G11): Q_Jη + Q_Jξ with dof = m_total − n.

Reports at equal times: system 1 first (:func:`merge_order`); Λ does not depend on it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from skytrack.identify.kalman import FilterBank
from skytrack.identify.model import IdentificationModel

#: decision codes of :meth:`SequentialPairTest.decide`
SAME, DIFFERENT, INSUFFICIENT = "same", "different", "insufficient"
SYSTEMS = (1, 2)
STATISTICS = ("four-forms", "joint-only")


def merge_order(time: np.ndarray, system: np.ndarray) -> np.ndarray:
    """The merged stream's order: by time, system 1 before system 2 at equal times, then input order."""
    return np.lexsort((np.arange(len(time)), np.asarray(system), np.asarray(time)))


@dataclass(frozen=True)
class PairForms:
    """The four quadratic forms of (20a) per pair, with Λ and its degrees of freedom."""

    joint_eta: np.ndarray
    joint_xi: np.ndarray
    eta: np.ndarray
    xi: np.ndarray
    statistic: np.ndarray
    dof: np.ndarray


class SequentialPairTest:
    """Spec 001 R4: the sequential pair test over K pairs at once.

    ``model_xi`` is the motion model of object 0 (the system-2 filter, F_0 of the paper);
    by default the same as ``model`` (R1).  ``init`` is ``"diffuse"`` (default, R3a) or
    ``"prior"`` with ``x0``, ``P0``, ``t0`` (R3b; every filter starts from that prior).
    """

    def __init__(self, model: IdentificationModel, pairs: int = 1, *, model_xi: IdentificationModel | None = None,
                 init: str = "diffuse", x0=None, P0=None, t0: float | None = None,
                 statistic: str = "four-forms"):
        if statistic not in STATISTICS:
            raise ValueError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
        model_xi = model if model_xi is None else model_xi
        if model_xi.n != model.n:
            raise ValueError("the models of object 1 and object 0 must have the same state dimension")
        self.model, self.model_xi, self.init, self.statistic_kind = model, model_xi, init, statistic
        prior = dict(init=init, x0=x0, P0=P0, t0=t0)
        self.joint = FilterBank(model, pairs, **prior)
        self.eta = FilterBank(model, pairs, **prior)
        self.xi = FilterBank(model_xi, pairs, **prior)
        self.joint_eta = np.zeros(pairs)  # Q_Jη
        self.joint_xi = np.zeros(pairs)  # Q_Jξ
        self.reports = 0

    def __len__(self) -> int:
        return len(self.joint)

    # ------------------------------------------------------------------ reports
    def add(self, system: int, t, z, V, H=None, rows=None) -> None:
        """One report of ``system`` (1 = η, 2 = ξ) for each pair in ``rows`` (default: all).

        ``t`` scalar or ``[K]``; ``z`` ``[K, m]`` (or ``[m]`` for all rows); ``V`` ``[m, m]`` or
        ``[K, m, m]``; ``H`` ``[m, n]`` or ``[K, m, n]``, default the first m state components
        (positions, then velocities).  Errors name the report: NaN, a covariance that is not
        positive definite, an unknown system, time going backwards.
        """
        if system not in SYSTEMS:
            raise ValueError(f"unknown system {system!r} (report {self.reports}): expected 1 (eta) or 2 (xi)")
        rows = np.arange(len(self)) if rows is None else np.atleast_1d(np.asarray(rows, dtype=np.intp))
        k, n = len(rows), self.model.n
        z = np.asarray(z, float)
        z = np.broadcast_to(z, (k, z.shape[-1])) if z.ndim == 1 else z.reshape(k, -1)
        m = z.shape[1]
        V = np.broadcast_to(np.asarray(V, float), (k, m, m))
        H = np.eye(m, n) if H is None else np.asarray(H, float)
        H = np.broadcast_to(H, (k, m, n))
        self._check(t, z, V, H)
        t = np.broadcast_to(np.asarray(t, float), (k,))
        own = self.eta if system == 1 else self.xi
        for bank in (self.joint, own):
            bank.predict(rows, t)
        joint = self.joint.update(rows, z, V, H)
        own.update(rows, z, V, H)
        (self.joint_eta if system == 1 else self.joint_xi)[rows] += joint.quadratic
        self.reports += 1

    def _check(self, t, z, V, H) -> None:
        where = f"report {self.reports}"
        if not np.all(np.isfinite(np.asarray(t, float))):
            raise ValueError(f"{where}: time is not finite")
        if not np.all(np.isfinite(z)):
            raise ValueError(f"{where}: the measurement has NaN or infinite values")
        if not (np.all(np.isfinite(V)) and np.all(np.isfinite(H))):
            raise ValueError(f"{where}: the covariance or measurement matrix has NaN or infinite values")
        if np.any(np.linalg.eigvalsh(0.5 * (V + np.swapaxes(V, -1, -2))).min(axis=-1) <= 0):
            raise ValueError(f"{where}: the measurement covariance is singular or not positive definite")

    def run(self, time, system, z, V, H=None) -> list[PairForms]:
        """Feed a whole report stream (one pair, or the same stream to all pairs) in merge order;
        returns the forms after every report (TV-3b's sequence)."""
        time, system = np.asarray(time, float), np.asarray(system)
        history = []
        for i in merge_order(time, system):
            self.add(int(system[i]), time[i], np.asarray(z)[i], np.asarray(V)[i],
                     None if H is None else np.asarray(H)[i])
            history.append(self.forms())
        return history

    # ------------------------------------------------------------------ statistics
    def forms(self) -> PairForms:
        """The four quadratic forms, Λ and dof per pair (R4; R15 with ``statistic='joint-only'``)."""
        if self.statistic_kind == "joint-only":
            statistic = self.joint_eta + self.joint_xi
            dof = self.joint.m - self.model.n
        else:
            statistic = self.joint_eta + self.joint_xi - self.eta.J - self.xi.J
            dof = self.eta.rank + self.xi.rank - self.joint.rank
        return PairForms(self.joint_eta.copy(), self.joint_xi.copy(), self.eta.J.copy(), self.xi.J.copy(),
                         statistic, np.asarray(dof))

    @property
    def statistic(self) -> np.ndarray:
        """Λ of (20a) per pair."""
        return self.forms().statistic

    @property
    def dof(self) -> np.ndarray:
        return self.forms().dof

    @property
    def logdet_difference(self) -> np.ndarray:
        """D = Σ ln det R_ζ − Σ ln det R_η − Σ ln det R_ξ (gap G1)."""
        return self.joint.L - self.eta.L - self.xi.L

    def decide(self, threshold, dof_min: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Decisions (20a) per pair and the threshold used (R5).  ``threshold`` is a
        :class:`~skytrack.identify.threshold.Threshold` or a number (the literal ``h=`` mode)."""
        from skytrack.identify.threshold import Threshold

        forms = self.forms()
        dof_min = self.model.n if dof_min is None else dof_min
        rule = threshold if isinstance(threshold, Threshold) else Threshold(h=float(threshold))
        h = rule.value(forms.dof, covariance_sum=self._covariance_sum_for(rule))
        decision = np.where(forms.statistic > h, DIFFERENT, SAME).astype(object)
        decision[forms.dof < dof_min] = INSUFFICIENT
        return decision, h

    def _covariance_sum_for(self, rule) -> np.ndarray | None:
        if not rule.needs_covariance:
            return None
        return self.separate_covariance_sum()

    def separate_covariance_sum(self, t=None) -> np.ndarray:
        """P_η + P_ξ at one common time (default: the later of the two filters' times)."""
        rows = np.arange(len(self))
        if not (np.all(self.eta.full) and np.all(self.xi.full)):
            raise ValueError("P_eta + P_xi needs both separate filters at full information rank")
        t = np.maximum(self.eta.t, self.xi.t) if t is None else np.broadcast_to(np.asarray(t, float), rows.shape)
        _, P_eta = self.eta.estimate_at(rows, t)
        _, P_xi = self.xi.estimate_at(rows, t)
        return P_eta + P_xi

    def log_odds(self, prior_same: float = 0.5, include_logdet: bool = True,
                 object_density: float | None = None) -> np.ndarray:
        """log P(θ=1 | ζ) − log P(θ=0 | ζ) per pair (R6), without underflow.

        Prior mode: ln BF = −(Λ + D)/2 (G1); ``include_logdet=False`` drops D — the paper's
        literal (14a) — and warns.  Diffuse mode needs ``object_density`` β (density of
        objects in state space, no default): ln BF = −Λ/2 − ½ ln det(2π(P_η + P_ξ)) − ln β,
        exact for Q = 0 with full-rank separate filters, flagged approximate for Q > 0.
        """
        if not 0.0 < prior_same < 1.0:
            raise ValueError(f"prior_same must be in (0, 1), got {prior_same}")
        if self.statistic_kind != "four-forms":
            raise ValueError("the posterior needs statistic='four-forms'")
        prior_logit = np.log(prior_same) - np.log1p(-prior_same)
        lam = self.statistic
        if self.init == "prior":
            if object_density is not None:
                raise ValueError("object_density is the diffuse-mode form; in prior mode the prior is N(x0, P0)")
            if not include_logdet:
                warnings.warn("include_logdet=False is the paper's literal (14a): the result is not a calibrated "
                              "probability (spec 001 gap G1)", stacklevel=2)
                return prior_logit - 0.5 * lam
            return prior_logit - 0.5 * (lam + self.logdet_difference)
        if object_density is None or not object_density > 0:
            raise ValueError("after a diffuse start the posterior needs object_density (beta > 0): the density of "
                             "objects in state space (spec 001 R6); it has no default")
        if self._has_process_noise():
            warnings.warn("with process noise the density-mode posterior is approximate (spec 001 R6)", stacklevel=2)
        S = self.separate_covariance_sum()
        _, logdet = np.linalg.slogdet(2.0 * np.pi * S)
        return prior_logit - 0.5 * lam - 0.5 * logdet - np.log(object_density)

    def posterior(self, prior_same: float = 0.5, include_logdet: bool = True,
                  object_density: float | None = None) -> np.ndarray:
        """P(θ = 1 | ζ_1^k) per pair (R6); see :meth:`log_odds`."""
        return logistic(self.log_odds(prior_same, include_logdet, object_density))

    def _has_process_noise(self) -> bool:
        return bool(np.any(self.model.Q(np.array([1.0])) != 0) or np.any(self.model_xi.Q(np.array([1.0])) != 0))

    # ------------------------------------------------------------------ estimates
    def joint_estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The joint filter's state and covariance per pair (the R14 ``fusion='joint'`` estimate)."""
        return self.joint.x.copy(), self.joint.P.copy()


def logistic(log_odds: np.ndarray) -> np.ndarray:
    """1 / (1 + e^{-a}) without overflow."""
    a = np.asarray(log_odds, float)
    return np.where(a >= 0, 1.0 / (1.0 + np.exp(-np.abs(a))), np.exp(-np.abs(a)) / (1.0 + np.exp(-np.abs(a))))
