"""Checks of study E4 (spec 003 §6): the CI-sized assertions (i)-(iv) and the expected results Q1-Q5.

:func:`check_cases` lists the configurations the checks read (the reference scenario with
beta = 5 deg, q = 25: policies ``track`` and ``always``, IFF error rates 0-0.3, and beta in {5, 10}
x q in {1, 25} for Q3); :func:`ci_checks` and :func:`qualitative_checks` return
:class:`~skytrack.studies.fuzzy.common.Check` rows (condition, the numbers behind it, its label, verdict).  (iv) is TV13 (c): the ``nn`` and ``ml``
decisions are bit-identical across every IFF setting and policy.

The spec's assertions carry their own margins.  Q1-Q5 are statements about directions ("lower
than", "about"); where a direction is claimed between two methods on the same runs, it is
checked with a margin of two standard errors of the difference (``se = sqrt(se_a^2 + se_b^2)``,
conservative for paired runs; CAR's over runs) so that a 100-run check does not fail on sampling
noise alone.  Q3 is stated for close crossings: ``ml`` swaps more than ``nn`` at beta = 5 deg,
and not less at beta = 10 deg (where, at q = 1, no method swaps in this geometry).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from skytrack.studies.fuzzy.common import Check
from skytrack.studies.fuzzy.crossing import ERROR_RATES, CrossingCase, cell

#: margin, in standard errors of the difference, of the qualitative checks
SE_MARGIN = 2.0


def _verdict(name: str, holds, measured: str) -> Check:
    """A verdict row: ``name`` is "<label> <condition>", e.g. "(i) always, errors 0: swap(crisp) <= 0.05"."""
    label, _, condition = name.partition(" ")
    return Check(condition, measured, f"spec 003 §6 {label}", bool(holds))


def check_cases() -> list[CrossingCase]:
    """The configurations :func:`ci_checks` and :func:`qualitative_checks` read."""
    cases = [CrossingCase(sweep="check", policy="track"),
             CrossingCase(sweep="check", policy="track", p_flip=0.2, p_code=0.2)]
    cases += [CrossingCase(sweep="check", policy="always", p_flip=e, p_code=e) for e in ERROR_RATES]
    cases += [CrossingCase(sweep="check", beta_deg=b, q=q) for b in (5.0, 10.0) for q in (1.0, 25.0)
              if (b, q) != (5.0, 25.0)]
    return cases


def _at(table, method, policy="track", error=0.0, beta=5.0, q=25.0) -> pd.Series:
    return cell(table, method, policy=policy, p_flip=error, p_code=error, beta_deg=beta, q=q)


def _margin(a: pd.Series, b: pd.Series, column: str) -> float:
    se = f"{column}_se_runs" if column == "car" else f"{column}_se"
    return SE_MARGIN * math.hypot(a[se], b[se])


def ci_checks(table: pd.DataFrame, identical_decisions: bool) -> list[Check]:
    """The spec's CI-sized assertions (i)-(iv) on a table holding :func:`check_cases`."""
    a0 = {m: _at(table, m, "always") for m in ("nn", "fuzzy", "fuzzy-global", "crisp")}
    a2 = {m: _at(table, m, "always", 0.2) for m in ("nn", "fuzzy", "crisp")}
    t0 = {m: _at(table, m) for m in ("nn", "fuzzy", "fuzzy-global")}
    return [
        _verdict("(i) always, errors 0: swap(fuzzy-global) <= 0.05", a0["fuzzy-global"].swap <= 0.05,
              f"{a0['fuzzy-global'].swap:.3f}"),
        _verdict("(i) always, errors 0: swap(crisp) <= 0.05", a0["crisp"].swap <= 0.05, f"{a0['crisp'].swap:.3f}"),
        _verdict("(i) always, errors 0: swap(nn) >= 0.12", a0["nn"].swap >= 0.12, f"{a0['nn'].swap:.3f}"),
        _verdict("(i) always, errors 0: CAR(fuzzy) >= CAR(nn) + 0.08", a0["fuzzy"].car >= a0["nn"].car + 0.08,
              f"{a0['fuzzy'].car:.3f} vs {a0['nn'].car:.3f}"),
        _verdict("(ii) always, errors 0.2: CAR(crisp) <= CAR(nn) - 0.05", a2["crisp"].car <= a2["nn"].car - 0.05,
              f"{a2['crisp'].car:.3f} vs {a2['nn'].car:.3f}"),
        _verdict("(ii) always, errors 0.2: broken(crisp) >= 0.3", a2["crisp"].broken >= 0.3, f"{a2['crisp'].broken:.3f}"),
        _verdict("(ii) always, errors 0.2: CAR(fuzzy) >= CAR(crisp) + 0.1", a2["fuzzy"].car >= a2["crisp"].car + 0.1,
              f"{a2['fuzzy'].car:.3f} vs {a2['crisp'].car:.3f}"),
        _verdict("(iii) track, errors 0: |swap(fuzzy) - swap(nn)| <= 0.1", abs(t0["fuzzy"].swap - t0["nn"].swap) <= 0.1,
              f"{t0['fuzzy'].swap:.3f} vs {t0['nn'].swap:.3f}"),
        _verdict("(iii) track, errors 0: swap(fuzzy-global) <= swap(fuzzy) + 0.03",
              t0["fuzzy-global"].swap <= t0["fuzzy"].swap + 0.03,
              f"{t0['fuzzy-global'].swap:.3f} vs {t0['fuzzy'].swap:.3f}"),
        _verdict("(iv) TV13 (c): nn and ml decisions identical across IFF settings and policies", identical_decisions,
              "bit-identical" if identical_decisions else "decisions differ"),
    ]


def qualitative_checks(table: pd.DataFrame) -> list[Check]:
    """Q1-Q5 of spec 003 §6 on a table holding :func:`check_cases`."""
    checks = []
    # Q1: under the paper's policy the features hardly act, whatever the error rate
    for error in (0.0, 0.2):
        nn = _at(table, "nn", error=error)
        spread = max(abs(_at(table, m, error=error).swap - nn.swap) for m in ("fuzzy", "crisp"))
        checks.append(_verdict(f"Q1 track, errors {error:g}: swap(fuzzy), swap(crisp) within 0.1 of swap(nn)",
                            spread <= 0.1, f"largest difference {spread:.3f}"))
    drift = abs(_at(table, "fuzzy", error=0.2).swap - _at(table, "fuzzy").swap)
    checks.append(_verdict("Q1 track: IFF errors 0 -> 0.2 change swap(fuzzy) by <= 0.1", drift <= 0.1, f"{drift:.3f}"))
    # Q2: the global assignment never swaps more than greedy fuzzy
    worse = []
    for _, row in table[table.method == "fuzzy"].iterrows():
        settings = dict(policy=row.policy, p_flip=row.p_flip, p_code=row.p_code, beta_deg=row.beta_deg, q=row.q)
        glob = cell(table, "fuzzy-global", **settings)
        if glob.swap > row.swap + _margin(glob, row, "swap"):
            worse.append(f"{settings}: {glob.swap:.3f} > {row.swap:.3f}")
    checks.append(_verdict("Q2 swap(fuzzy-global) <= swap(fuzzy) in every configuration (2 SE)", not worse,
                        "; ".join(worse) or f"{(table.method == 'fuzzy').sum()} configurations"))
    # Q3: the determinant term of ml pulls plots to the tighter track in close crossings
    for beta in (5.0, 10.0):
        for q in (1.0, 25.0):
            ml, nn = _at(table, "ml", beta=beta, q=q), _at(table, "nn", beta=beta, q=q)
            holds, relation = (ml.swap > nn.swap, ">") if beta == 5.0 else (ml.swap >= nn.swap, ">=")
            checks.append(_verdict(f"Q3 beta {beta:g} deg, q {q:g}: swap(ml) {relation} swap(nn)", holds,
                                f"{ml.swap:.3f} vs {nn.swap:.3f}"))
    # Q4: continuous error-free interrogation nearly removes swaps for the feature rules
    for method in ("fuzzy", "fuzzy-global", "crisp"):
        row = _at(table, method, "always")
        checks.append(_verdict(f"Q4 always, errors 0: {method} swap <= 0.02 and CAR > 0.98",
                            row.swap <= 0.02 + SE_MARGIN * row.swap_se and row.car > 0.98,
                            f"swap {row.swap:.3f}, CAR {row.car:.3f}"))
    same = all(_at(table, m, "always").car == _at(table, m).car for m in ("nn", "ml"))
    checks.append(_verdict("Q4 nn and ml unaffected by the policy", same, "identical CAR" if same else "differ"))
    checks += _q5(table)
    return checks


def _q5(table: pd.DataFrame) -> list[Check]:
    """Q5: crisp breaks tracks as errors grow; the fuzzy rules degrade gradually."""
    checks = []
    crisp_swaps = [float(_at(table, "crisp", "always", e).swap) for e in ERROR_RATES]
    checks.append(_verdict("Q5 swap(crisp) ~ 0 at every error rate (<= 0.02)", max(crisp_swaps) <= 0.02,
                        ", ".join(f"{s:.3f}" for s in crisp_swaps)))
    c10, n10 = _at(table, "crisp", "always", 0.1), _at(table, "nn", "always", 0.1)
    checks.append(_verdict("Q5 errors 0.1: CAR(crisp) at or below CAR(nn) (2 SE)", c10.car <= n10.car + _margin(c10, n10, "car"),
                        f"{c10.car:.3f} vs {n10.car:.3f}"))
    for error in (0.2, 0.3):
        c, n = _at(table, "crisp", "always", error), _at(table, "nn", "always", error)
        checks.append(_verdict(f"Q5 errors {error:g}: CAR(crisp) far below CAR(nn) (by >= 0.1)", c.car <= n.car - 0.1,
                            f"{c.car:.3f} vs {n.car:.3f}"))
    for error in ERROR_RATES:
        nn = _at(table, "nn", "always", error)
        for method in ("fuzzy", "fuzzy-global"):
            row = _at(table, method, "always", error)
            if error <= 0.2:
                checks.append(_verdict(f"Q5 errors {error:g}: CAR({method}) above CAR(nn) (2 SE)",
                                    row.car >= nn.car - _margin(row, nn, "car"), f"{row.car:.3f} vs {nn.car:.3f}"))
            checks.append(_verdict(f"Q5 errors {error:g}: swap({method}) below swap(nn) (2 SE)",
                                row.swap <= nn.swap + _margin(row, nn, "swap"), f"{row.swap:.3f} vs {nn.swap:.3f}"))
    f30, n30 = _at(table, "fuzzy", "always", 0.3), _at(table, "nn", "always", 0.3)
    checks.append(_verdict("Q5 errors 0.3: CAR(fuzzy) reaches CAR(nn) (within 0.05)", abs(f30.car - n30.car) <= 0.05,
                        f"{f30.car:.3f} vs {n30.car:.3f}"))
    return checks


def decisions_identical(kept: list[tuple[CrossingCase, dict]], methods=("nn", "ml")) -> bool:
    """TV13 (c): each method's decisions are the same arrays in every kept configuration of the
    same geometry and tracker (IFF settings and policy may differ)."""
    groups: dict[tuple, list] = {}
    for case, decisions in kept:
        groups.setdefault((case.beta_deg, case.q, case.d_e, case.dh, case.missing_iff), []).append(decisions)
    for group in groups.values():
        for method in methods:
            runs = [k[method].track_id for k in group if method in k]
            if any(not np.array_equal(runs[0], other) for other in runs[1:]):
                return False
    return True


#: the spec's indicative cells (§6 E4, beta = 5 deg, 200 runs): (policy, errors) -> method -> (CAR, swap, broken)
_NN, _ML = (0.82, 0.26, 0.02), (0.79, 0.39, 0.04)
SPEC_INDICATIVE: dict[tuple[str, float], dict[str, tuple[float, float, float]]] = {
    ("track", 0.0): {"nn": _NN, "ml": _ML, "fuzzy": (0.82, 0.25, 0.04), "fuzzy-global": (0.85, 0.17, 0.04),
                     "crisp": (0.82, 0.25, 0.02)},
    ("track", 0.2): {"nn": _NN, "ml": _ML, "fuzzy": (0.82, 0.25, 0.04), "fuzzy-global": (0.85, 0.17, 0.04),
                     "crisp": (0.82, 0.25, 0.02)},
    ("always", 0.0): {"nn": _NN, "ml": _ML, "fuzzy": (0.985, 0.005, 0.015), "fuzzy-global": (0.993, 0.005, 0.013),
                      "crisp": (0.991, 0.0, 0.005)},
    ("always", 0.05): {"nn": _NN, "ml": _ML, "fuzzy": (0.956, 0.05, 0.04), "fuzzy-global": (0.976, 0.02, 0.05),
                       "crisp": (0.901, 0.0, 0.06)},
    ("always", 0.1): {"nn": _NN, "ml": _ML, "fuzzy": (0.908, 0.12, 0.09), "fuzzy-global": (0.944, 0.06, 0.10),
                      "crisp": (0.820, 0.0, 0.20)},
    ("always", 0.2): {"nn": _NN, "ml": _ML, "fuzzy": (0.849, 0.20, 0.19), "fuzzy-global": (0.879, 0.13, 0.19),
                      "crisp": (0.680, 0.0, 0.56)},
    ("always", 0.3): {"nn": _NN, "ml": _ML, "fuzzy": (0.812, 0.19, 0.25), "fuzzy-global": (0.839, 0.15, 0.26),
                      "crisp": (0.546, 0.0, 0.85)},
}
#: the spec's bounds on the standard errors of its indicative cells (200 runs)
SPEC_SE = {"car": 0.015, "swap": 0.025}


def indicative_markdown(table: pd.DataFrame, seed: int,
                        methods=("nn", "ml", "fuzzy", "fuzzy-global", "crisp")) -> str:
    """The spec's indicative table with this run's cells beside the spec's (``CAR / swap / broken``).

    A cell is marked ``*`` when CAR or swap differs from the spec's by more than two standard
    errors of a difference of two independent estimates at the spec's SE bounds
    (``2 sqrt(2) SE``: 0.042 for CAR, 0.071 for swap)."""
    runs = int(table["runs"].max())
    lines = [f"| configuration ({runs} runs, seed {seed}) | " + " | ".join(methods) + " |",
             "|---|" + "---|" * len(methods)]
    limits = {k: 2 * math.sqrt(2) * v for k, v in SPEC_SE.items()}
    for (policy, error), spec_row in SPEC_INDICATIVE.items():
        cells = []
        for method in methods:
            try:
                row = _at(table, method, policy, error)
            except KeyError:
                cells.append("–")
                continue
            car, swap, broken = spec_row[method]
            off = abs(row.car - car) > limits["car"] or abs(row.swap - swap) > limits["swap"]
            cells.append(f"{row.car:.3f}/{row.swap:.3f}/{row.broken:.3f} ({car:g}/{swap:g}/{broken:g}){' *' if off else ''}")
        lines.append(f"| policy {policy}, errors {error:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
