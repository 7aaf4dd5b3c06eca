"""Spec 003 association layer: tables (TV1), gate (TV2), scores (TV6-TV8), regions (TV9),
greedy vs global (TV10), Monte Carlo properties (TV11)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.association.features import (CRISP_TABLES, FOE, FRIEND, MISSING, PAPER_TABLES, UNDETERMINED,
                                           UNIT_TABLES, CategoryTable, FeatureTables, PAPER_G_TABLE)
from skytrack.association.identity_rules import (NEW, RuleConfig, coordinate_terms, decide_global, decide_greedy,
                                                 diagnostics, gate_gamma, new_object_score, score_pairs)
from skytrack.core.chi2 import chi2_cdf

REL = 1e-9
NAMES = {"friend": FRIEND, "foe": FOE, "undetermined": UNDETERMINED}


def close(value, expected, rel=REL):
    return value == pytest.approx(expected, rel=rel, abs=1e-12)


# --- TV1 --------------------------------------------------------------------------------------

def test_tv1_nationality_table_entries():
    for (h, z), mu in PAPER_G_TABLE.items():
        assert math.exp(PAPER_TABLES.log_mu_g(NAMES[h], NAMES[z])) == pytest.approx(mu, rel=1e-15)
    assert len(PAPER_G_TABLE) == 9


def test_tv1_number_table_and_missing_values():
    code_1234, code_5670 = int("1234", 8), int("5670", 8)
    mu_n = lambda h, z: math.exp(PAPER_TABLES.log_mu_n(h, z))  # noqa: E731
    assert mu_n(code_1234, code_1234) == pytest.approx(0.9)
    assert mu_n(code_1234, code_5670) == pytest.approx(0.1)
    assert mu_n(code_1234, MISSING) == 1.0
    assert mu_n(MISSING, code_1234) == 1.0
    assert math.exp(PAPER_TABLES.log_mu_g(FRIEND, MISSING)) == pytest.approx(0.5)
    assert math.exp(PAPER_TABLES.log_mu_g(UNDETERMINED, MISSING)) == pytest.approx(0.8)
    assert math.exp(PAPER_TABLES.log_mu_g(MISSING, MISSING)) == pytest.approx(0.8)  # no reply yet = undetermined
    neutral = FeatureTables(missing_iff="neutral")
    assert neutral.log_mu_g(FRIEND, MISSING) == 0.0
    assert neutral.log_mu_g(UNDETERMINED, MISSING) == 0.0
    # an explicit "undetermined" reply still uses the table
    assert math.exp(neutral.log_mu_g(FRIEND, UNDETERMINED)) == pytest.approx(0.5)


def test_tv1_invalid_tables_are_rejected():
    too_big = dict(PAPER_G_TABLE)
    too_big[("friend", "friend")] = 1.2
    with pytest.raises(ValueError, match="outside"):
        FeatureTables(g_table=too_big)
    missing_key = {k: v for k, v in PAPER_G_TABLE.items() if k != ("foe", "undetermined")}
    with pytest.raises(ValueError, match="foe.*undetermined"):
        FeatureTables(g_table=missing_key)
    with pytest.raises(ValueError, match="missing_iff"):
        FeatureTables(missing_iff="ignore")
    # zero means forbidden
    assert CRISP_TABLES.log_mu_g(FRIEND, FOE) == -np.inf


def test_extra_category_table_same_missing_rule():
    size = CategoryTable(("small", "large"), {("small", "small"): 0.9, ("small", "large"): 0.3,
                                              ("large", "small"): 0.3, ("large", "large"): 0.9})
    tables = FeatureTables(extra={"size": size})
    got = tables.log_mu_extra({"size": np.array([0, 0, -1])}, {"size": np.array([0, 1, 1])}, 3)
    assert np.allclose(np.exp(got), [0.9, 0.3, 1.0])
    with pytest.raises(ValueError, match="size"):
        tables.log_mu_extra({}, {}, 3)


# --- TV2 --------------------------------------------------------------------------------------

def test_tv2_gate_and_new_object_membership():
    g4 = gate_gamma(4, 0.99)
    assert close(g4, 13.276704135987622)
    assert close(new_object_score(RuleConfig(), 4), -6.638352067993811)
    assert close(math.exp(-g4 / 2), 1.3091829115735537e-3)
    assert close(math.exp(-g4 / 2) * (1 + g4 / 2), 0.01)
    g3 = gate_gamma(3, 0.99)
    assert close(g3, 11.344866730144373)
    assert close(math.exp(-g3 / 2), 3.43948556075485e-3)
    assert close(math.erf(math.sqrt(g3 / 2)) - math.sqrt(2 * g3 / math.pi) * math.exp(-g3 / 2), 0.99)


# --- TV6 --------------------------------------------------------------------------------------

S6 = np.array([[2500, 0, 0, 60], [0, 4e-5, 1e-5, 0], [0, 1e-5, 2.5e-5, 0], [60, 0, 0, 16]])
NU6 = np.array([75, 0.006, -0.004, 3])


def test_tv6_exact_identity_full():
    d2, logdet = coordinate_terms(NU6[None], S6[None])
    s = score_pairs(RuleConfig(rule="fuzzy"), d2, logdet, 4)
    assert close(d2[0], 4.593345543345543)
    assert close(logdet[0], -10.326302298979405)
    assert close(s.columns["ln_p"][0], -0.809275755001760)
    assert close(s.columns["ln_mu"][0], -2.296672771672772)
    assert close(s.columns["ln_mu"][0] - s.columns["ln_p"][0], -1.487397016671012)
    assert close(s.columns["ln_mu"][0] - s.columns["ln_p"][0], 0.5 * (4 * math.log(2 * math.pi) + logdet[0]))
    assert close(math.exp(s.columns["ln_mu"][0]), 0.1005929834, rel=1e-9)
    assert close(math.exp(s.columns["ln_p"][0]), 0.4451803692, rel=1e-9)


def test_tv6_diagonal_flag_is_the_product_of_1d_densities():
    d2, logdet = coordinate_terms(NU6[None], S6[None], innovation_cov="diagonal")
    s = score_pairs(RuleConfig(rule="fuzzy", innovation_cov="diagonal"), d2, logdet, 4)
    assert close(d2[0], 4.3525)
    assert close(logdet[0], -10.126631103850336)
    assert close(s.columns["ln_p"][0], -0.788688580893522)
    sd = np.sqrt(np.diag(S6))
    one_d = np.sum(-0.5 * (NU6 / sd) ** 2 - np.log(sd) - 0.5 * math.log(2 * math.pi))
    assert close(s.columns["ln_p"][0], one_d)
    assert close(s.columns["ln_mu"][0], -2.17625)


def test_non_positive_definite_covariance_names_the_track():
    bad = S6.copy()
    bad[0, 0] = -1.0
    with pytest.raises(ValueError, match="track 17"):
        coordinate_terms(np.stack([NU6, NU6]), np.stack([S6, bad]), track_id=np.array([5, 17]))
    with pytest.raises(ValueError, match="track 17"):
        coordinate_terms(np.stack([NU6, NU6]), np.stack([S6, bad]), "diagonal", track_id=np.array([5, 17]))


# --- TV7, TV8 ----------------------------------------------------------------------------------

def _two_track_choice(rule, d2, logdet, track_iff, track_code, plot_iff, plot_code, tables=PAPER_TABLES):
    config = RuleConfig(rule=rule, mode="greedy", tables=tables)
    eff = config.effective_tables
    scores = score_pairs(config, np.asarray(d2, float), np.asarray(logdet, float), 4,
                         eff.log_mu_g(track_iff, plot_iff), eff.log_mu_n(track_code, plot_code))
    choice = decide_greedy(scores.score[None], scores.hypothesis[None], new_object_score(config, [4]))
    return "AB"[choice[0]] if choice[0] != NEW else "new", scores


def test_tv7_feature_overrides_geometry():
    SA = np.diag([50.0**2, 0.005**2, 0.005**2, 3.0**2])
    nus = np.array([[50, 0.005, 0, 0], [100, 0, 0.005, 0]])
    d2, logdet = coordinate_terms(nus, np.stack([SA, SA]))
    assert np.allclose(d2, [2.0, 5.0], rtol=1e-12)
    codes = np.array([int("1234", 8), int("5670", 8)])
    iffs = np.array([FRIEND, FOE])
    # (a) plot foe / 5670
    plot = (np.array([FOE, FOE]), np.array([codes[1]] * 2))
    got = {r: _two_track_choice(r, d2, logdet, iffs, codes, *plot) for r in ("fuzzy", "crisp", "nn", "ml")}
    assert close(got["fuzzy"][1].columns["ln_mu"][0], -4.912023005428146)
    assert close(got["fuzzy"][1].columns["ln_mu"][1], -2.828504066972036)
    assert [got[r][0] for r in ("fuzzy", "crisp", "nn", "ml")] == ["B", "B", "A", "A"]
    assert close(got["ml"][1].score[0], 0.910245306181, rel=1e-11)
    assert close(got["ml"][1].score[1], -0.589754693819, rel=1e-11)
    assert close(2 * math.log(36), 7.167037876912)
    # fuzzy keeps B while d_B^2 - d_A^2 < 2 ln 36
    for gap, expected in ((7.16, "B"), (7.17, "A")):
        assert _two_track_choice("fuzzy", [2.0, 2.0 + gap], logdet, iffs, codes, *plot)[0] == expected
    # (b) the plot has no reply and no number
    none = (np.array([MISSING] * 2), np.array([MISSING] * 2))
    choice, scores = _two_track_choice("fuzzy", d2, logdet, iffs, codes, *none)
    assert choice == "A" == _two_track_choice("nn", d2, logdet, iffs, codes, *none)[0]
    assert np.allclose(scores.columns["ln_mu"], [-1.693147180560, -3.193147180560], rtol=1e-12)


def test_tv7c_table_bias_of_missing_replies():
    SA = np.diag([50.0**2, 0.005**2, 0.005**2, 3.0**2])
    nus = np.array([[50, 0.005, 0, 0], [75, 0, 0.0025, 0]])
    d2, logdet = coordinate_terms(nus, np.stack([SA, SA]))
    iffs, codes = np.array([FRIEND, UNDETERMINED]), np.array([int("1234", 8), MISSING])
    none = (np.array([MISSING] * 2), np.array([MISSING] * 2))
    choice, scores = _two_track_choice("fuzzy", d2, logdet, iffs, codes, *none)
    assert choice == "B"
    assert np.allclose(scores.columns["ln_mu"], [-1.693147180560, -1.473143551314], rtol=1e-12)
    neutral = FeatureTables(missing_iff="neutral")
    choice, scores = _two_track_choice("fuzzy", d2, logdet, iffs, codes, *none, tables=neutral)
    assert choice == "A"
    assert np.allclose(scores.columns["ln_mu"], [-1.0, -1.25], rtol=1e-12)
    assert close(2 * math.log(1.6), 0.940007258491)


def test_tv8_ml_and_fuzzy_disagree_through_det_s():
    SA = np.diag([30.0**2, 0.002**2, 0.002**2, 1.5**2])
    SB = np.diag([120.0**2, 0.008**2, 0.008**2, 6.0**2])
    d2, logdet = coordinate_terms(np.array([[60, 0.002, 0.002, 0], [120, 0, 0, 0]]), np.stack([SA, SB]))
    assert np.allclose(d2, [6.0, 1.0], rtol=1e-12)
    assert close(logdet[0], -17.245107414148, rel=1e-11)
    assert close(logdet[1], -6.154752525189, rel=1e-11)
    iffs, codes = np.array([UNDETERMINED] * 2), np.array([MISSING] * 2)
    none = (np.array([MISSING] * 2), np.array([MISSING] * 2))
    ml, ml_scores = _two_track_choice("ml", d2, logdet, iffs, codes, *none)
    fz, fz_scores = _two_track_choice("fuzzy", d2, logdet, iffs, codes, *none)
    assert (ml, fz, _two_track_choice("nn", d2, logdet, iffs, codes, *none)[0]) == ("A", "B", "B")
    assert np.allclose(ml_scores.score, [1.946799574255, -1.098377870224], rtol=1e-11)
    assert np.allclose(fz_scores.score, [-3.223143551314, -0.723143551314], rtol=1e-11)
    assert close(logdet[1] - logdet[0], 8 * math.log(4))


# --- TV9 --------------------------------------------------------------------------------------

def _regions(rule, x, plot_features=None, step_tables=PAPER_TABLES):
    """Choice along the line of TV9 for plot offsets ``x``."""
    sig = np.array([50.0, 0.004, 0.004, 2.0])
    SA = np.diag(sig**2)
    SB = 9 * SA
    nu = np.zeros((2 * len(x), 4))
    nu[0::2, 0] = x
    nu[1::2, 0] = x - 300.0
    S = np.tile(np.stack([SA, SB]), (len(x), 1, 1))
    d2, logdet = coordinate_terms(nu, S)
    config = RuleConfig(rule=rule, mode="greedy", tables=step_tables)
    eff = config.effective_tables
    if plot_features is None:
        ln_g = ln_n = None
    else:
        track_iff = np.tile([FRIEND, FOE], len(x))
        track_code = np.tile([int("1234", 8), int("5670", 8)], len(x))
        ln_g = eff.log_mu_g(track_iff, np.full(2 * len(x), plot_features[0]))
        ln_n = eff.log_mu_n(track_code, np.full(2 * len(x), plot_features[1]))
    s = score_pairs(config, d2, logdet, 4, ln_g, ln_n)
    choice = decide_greedy(s.score.reshape(-1, 2), s.hypothesis.reshape(-1, 2), new_object_score(config, np.full(len(x), 4)))
    return np.array(["A", "B", "new"])[np.where(choice == NEW, 2, choice)]


def _boundaries(rule, features, tables):
    """Changes of choice along x in [-700, 1000], each located by bisection to 1e-6 m."""
    x = np.arange(-700.0, 1000.0, 0.5) + 0.25
    labels = _regions(rule, x, features, tables)
    out = []
    for i in np.flatnonzero(labels[1:] != labels[:-1]):
        lo, hi = x[i], x[i + 1]
        while hi - lo > 1e-6:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _regions(rule, np.array([mid]), features, tables)[0] == labels[i] else (lo, mid)
        out.append((labels[i], labels[i + 1], 0.5 * (lo + hi)))
    return out


@pytest.mark.parametrize("rule, features, expected", [
    ("ml", None, [("new", "B", -246.558), ("B", "A", -182.186), ("A", "B", 155.826), ("B", "new", 846.558)]),
    ("fuzzy", None, [("new", "B", -246.558), ("B", "A", -150.0), ("A", "B", 75.0), ("B", "new", 846.558)]),
    ("fuzzy", (FOE, int("5670", 8)), [("new", "B", -232.863), ("B", "new", 832.863)]),
])
def test_tv9_decision_regions(rule, features, expected):
    got = _boundaries(rule, features, PAPER_TABLES if features else UNIT_TABLES)
    assert [(a, b) for a, b, _ in got] == [(a, b) for a, b, _ in expected]
    for (_, _, at), (_, _, want) in zip(got, expected):
        assert abs(at - want) < 1e-3
    gamma = gate_gamma(4)
    assert close(50 * math.sqrt(gamma), 182.186, rel=3e-6)
    root = (-600 + math.sqrt(600**2 + 4 * 8 * (90000 + 22500 * 8 * math.log(3)))) / 16
    assert abs(root - 155.826) < 1e-3


# --- TV10 -------------------------------------------------------------------------------------

def test_tv10_greedy_and_global():
    score = np.array([[-0.5, -1.0], [-0.75, -3.0], [-8.0, -7.5]])
    new = np.full(3, -6.638352067993811)
    hyp = score >= new[:, None]
    glob = decide_global(score, hyp, new)
    assert glob.tolist() == [1, 0, NEW]
    total = -(score[0, 1] + score[1, 0] + new[2])
    assert close(total, 8.388352067994)
    assert decide_greedy(score, hyp, new).tolist() == [0, 0, NEW]


def test_global_assignment_matches_brute_force():
    rng = np.random.default_rng(3)
    from itertools import permutations
    for _ in range(40):
        m, n = int(rng.integers(1, 5)), int(rng.integers(0, 4))
        score = -rng.exponential(4.0, (m, n))
        new = np.full(m, -6.6)
        hyp = score >= new[:, None]
        choice = decide_global(score, hyp, new)
        got = sum(score[i, c] if c != NEW else new[i] for i, c in enumerate(choice))
        best = -np.inf
        options = list(range(n)) + [NEW] * m
        for perm in set(permutations(options, m)):
            if any(c != NEW and not hyp[i, c] for i, c in enumerate(perm)):
                continue
            best = max(best, sum(score[i, c] if c != NEW else new[i] for i, c in enumerate(perm)))
        assert got == pytest.approx(best, abs=1e-12)
        used = choice[choice != NEW]
        assert len(used) == len(set(used.tolist()))


def test_r12_ties_track_beats_new_and_lower_id_wins():
    new = np.array([-2.0])
    assert decide_greedy(np.array([[-2.0]]), np.array([[True]]), new).tolist() == [0]
    # equal scores: the lower track id wins, whatever the column order
    score = np.array([[-1.0, -1.0]])
    assert decide_greedy(score, np.array([[True, True]]), new, track_id=np.array([9, 4])).tolist() == [1]
    assert decide_greedy(score, np.array([[True, True]]), new, track_id=np.array([4, 9])).tolist() == [0]


def test_ml_global_needs_a_new_object_density():
    with pytest.raises(ValueError, match="ml_new_density"):
        RuleConfig(rule="ml", mode="global")
    config = RuleConfig(rule="ml", mode="global", ml_new_density=1e-3)
    assert new_object_score(config, [4])[0] == pytest.approx(math.log(1e-3))


def test_r13_diagnostic_rows():
    d2, logdet = coordinate_terms(np.stack([NU6, 2 * NU6]), np.stack([S6, S6]))
    s = score_pairs(RuleConfig(), d2, logdet, 4)
    rows = diagnostics(np.array([0, 0]), np.array([3, 8]), s, np.array([True, False]))
    for name in ("track_id", "d2", "logdet", "ln_p", "ln_mu_coord", "mu_G", "mu_N", "ln_mu", "chosen"):
        assert len(rows[name]) == 2
    assert np.allclose(rows["ln_mu"], -0.5 * rows["d2"] + np.log(rows["mu_G"] * rows["mu_N"]))


# --- TV11 -------------------------------------------------------------------------------------

def test_tv11_effective_gate_and_mean_membership():
    rng = np.random.default_rng(11)
    n = 400_000
    L = np.linalg.cholesky(S6)
    nu = rng.standard_normal((n, 4)) @ L.T
    d2, logdet = coordinate_terms(nu, np.broadcast_to(S6, (n, 4, 4)))
    gamma = gate_gamma(4)
    table = {1: 0.99, 0.8: 0.98787, 0.72: 0.98671, 0.5: 0.98181, 0.2: 0.96054, 0.18: 0.95692, 0.02: 0.75608}
    for product, probability in table.items():
        expected = chi2_cdf(gamma + 2 * math.log(product), 4)
        assert expected == pytest.approx(probability, abs=1e-5)
        kept = np.mean(-0.5 * d2 + math.log(product) >= -0.5 * gamma)
        se = math.sqrt(expected * (1 - expected) / n)
        assert abs(kept - expected) < 4 * se
    assert abs(np.mean(np.exp(-0.5 * d2)) - 0.25) < 0.002
