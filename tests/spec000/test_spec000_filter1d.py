"""Spec 000 R3-R6, R10, R11, R13 and TV4-TV7, TV-S: the 1-D Singer filter against the oracles."""

import inspect
import math

import numpy as np
import pytest
from scipy.stats import norm

from oracles import (
    exact_FQ,
    explicit_1d_pos,
    explicit_1d_posvel,
    paper_FQ,
    theorem1_coefficients,
    thm1_run,
    thm1_step,
    thm2,
)
from skytrack.filters import ManeuverSwitch, SingerFilter1D, SingerParams, steady_state
from skytrack.models import SingerAxisModel

DT, TAU, SIGMA_A = 10.0, 60.0, 1.0
M_N = np.array([1000.0, 200.0, 0.5])
GAMMA_N = np.array([[2500.0, 150.0, 2.0], [150.0, 40.0, 0.8], [2.0, 0.8, 0.6]])
H_POS = np.array([[1.0, 0.0, 0.0]])
H_POSVEL = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def model(disc="paper", tau=TAU, sigma_a=SIGMA_A):
    return SingerAxisModel(tau, sigma_a, disc)


def rel(actual, reference):
    """max |difference| / max |reference| (R11)."""
    actual, reference = np.asarray(actual, float), np.asarray(reference, float)
    return np.max(np.abs(actual - reference)) / np.max(np.abs(reference))


def oracle_FQ(disc, dt=DT, tau=TAU, sigma_a=SIGMA_A):
    return paper_FQ(dt, tau, sigma_a) if disc == "paper" else exact_FQ(dt, tau, sigma_a)


# --------------------------------------------------------------------------- TV4-TV6


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_tv4_one_scan_position_only(form):
    f = SingerFilter1D(model(), 50.0, update_form=form, m0=M_N, P0=GAMMA_N)
    em, eg = f.extrapolate(DT)
    np.testing.assert_allclose(em, [3025, 205, 0.4232408624453], rtol=1e-12)
    np.testing.assert_allclose(eg, [[12000, 990, 33.85926899562], [990, 116, 5.756075729256],
                                    [33.85926899562, 5.756075729256, 0.7133874757705]], rtol=1e-11)
    out = f.step(3050.0, True, DT)
    assert out.S[0, 0] == pytest.approx(14500, rel=1e-12)
    np.testing.assert_allclose(out.K[:2, 0], [0.8275862068966, 0.06827586206897], rtol=1e-12)
    assert out.K[2, 0] == pytest.approx(0.002335122, abs=1e-9)
    assert out.nu[0] == pytest.approx(25.0, rel=1e-12)
    assert out.d2 == pytest.approx(0.04310344827586207, rel=1e-12)
    np.testing.assert_allclose(out.m, [3045.689655172, 206.7068965517, 0.4816189124378], rtol=1e-12)
    expected = np.array([[2068.965517241, 170.6896551724, 5.837804999246], [170.6896551724, 48.40689655172, 3.444304949555],
                         [5.837804999246, 3.444304949555, 0.6343219518451]])
    assert rel(out.P, expected) <= 1e-9
    np.testing.assert_array_equal(out.P, out.P.T)
    # the explicit Gamma quantities of (F7) for the same step
    _, _, gq = explicit_1d_pos(M_N, GAMMA_N, 3050.0, 1, DT, TAU, SIGMA_A, 50.0)
    np.testing.assert_allclose(gq["GH"][:3], [1200, 99, 3.3859268995624565], rtol=1e-14)
    assert gq["GD"] == pytest.approx(6.896551724137931e-4, rel=1e-14)
    assert gq["GS"] == pytest.approx(25.0, rel=1e-14)


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_tv5_one_scan_position_velocity(form):
    f = SingerFilter1D(model(), 50.0, "posvel", 5.0, update_form=form, m0=M_N, P0=GAMMA_N)
    out = f.step([3050.0, 215.0], True, DT)
    np.testing.assert_allclose(out.S, [[14500, 990], [990, 141]], rtol=1e-12)
    np.testing.assert_allclose(out.K, [[0.6688275084555, 2.325253664036], [0.02325253664036, 0.6594325441563],
                                       [-8.684310819058e-4, 0.04692072695279]], rtol=1e-11)
    np.testing.assert_allclose(out.m, [3064.973224352, 212.1756388576, 0.8707373549255], rtol=1e-12)
    expected = np.array([[1672.068771139, 58.13134160090, -2.171077704765], [58.13134160090, 16.48581360391, 1.173018173820],
                         [-2.171077704765, 1.173018173820, 0.4727126597649]])
    assert rel(out.P, expected) <= 1e-9
    assert out.d2 == pytest.approx(0.9800122134535889, rel=1e-12)
    _, _, gq = explicit_1d_posvel(M_N, GAMMA_N, 3050.0, 215.0, 1, DT, TAU, SIGMA_A, 50.0, 5.0)
    assert gq["GH"][3] == pytest.approx(11.6, rel=1e-14)
    assert gq["GH"][4] == pytest.approx(0.5756075729256176, rel=1e-13)
    assert gq["GDV"] == pytest.approx(9.394964299135663e-5, rel=1e-13)
    assert gq["GSV"] == pytest.approx(10.0, rel=1e-13)


def test_tv5_spurious_delta_factor_in_gamma_dv_is_wrong():
    """G4: with the OCR's extra leading Delta in Gamma_DV the update differs from TV5."""
    good, _, gq = explicit_1d_posvel(M_N, GAMMA_N, 3050.0, 215.0, 1, DT, TAU, SIGMA_A, 50.0, 5.0)
    h1, h2, h3, h4, h5 = gq["GH"]
    s2, v2 = 50.0**2 / DT, 25.0 / DT
    bad_gdv = DT * gq["GDV"]
    bad_m1 = 1000 + 2000 + 25 + ((h1 * (v2 + h4) - h2**2) * gq["GS"] + h2 * s2 * gq["GSV"]) * bad_gdv
    assert good[0] == pytest.approx(3064.973224352, rel=1e-12)
    assert abs(bad_m1 - 3064.973224352) > 100


@pytest.mark.parametrize("measurement", ["pos", "posvel"])
@pytest.mark.parametrize("z", [3050.0, None, math.nan, -7e5])
def test_tv6_missed_scan_is_pure_extrapolation(measurement, z):
    f = SingerFilter1D(model(), 50.0, measurement, 5.0, m0=M_N, P0=GAMMA_N)
    em, eg = f.extrapolate(DT)
    zz = None if z is None else ([z, z] if measurement == "posvel" else z)
    out = f.step(zz, False, DT)
    np.testing.assert_array_equal(out.m, em)
    np.testing.assert_array_equal(out.P, eg)
    np.testing.assert_allclose(em, [3025, 205, 0.4232408624453], rtol=1e-12)
    assert np.all(np.isnan(out.nu)) and math.isnan(out.d2) and np.all(out.K == 0)
    # S is still reported: it sizes the gate (R7)
    assert out.S[0, 0] == pytest.approx(12000 + 2500, rel=1e-12)


# --------------------------------------------------------------------------- TV7, R5


TV7_Z = (0.0, 2010.0, 4035.0, 6010.0, 8120.0, 10090.0, 12110.0)
TV7_P_A = (0.5, -1.2, 0.1, 2.0, -0.9, 0.3, 0.0)
TV7_P_B = (3.0, -0.85, 1.9, 0.0, -3.0, 0.01, -5.0)
TV7_FLAGS = (True, False, True, True, False, True)
TV7_PAPER = [
    ((1507.5, 150.75, 8.507141335151), (1875, 68.75, 0.8208671723566)),
    ((3440.357066757534, 235.821413351507, 7.201139671267), (20900.78086757, 256.6469328470, 0.8716457202419)),
    ((6013.224989031, 297.7889592898, 5.826648238597), (2445.754079945, 46.19588398211, 0.5306610103621)),
    ((8284.342477515, 264.9782999847, 1.556849507601), (2146.559201446, 49.91066311081, 0.5146160769394)),
    ((11011.96795274, 280.5467950607, 1.317844656589), (16042.18889627, 160.8651449877, 0.6522072214780)),
    ((12166.93572419, 180.5826033088, -1.862086121366), (2419.733236304, 46.59775507784, 0.5312605269058)),
]
TV7_GAMMA6_PAPER = [[2419.733236304, 159.5060666009, 4.197781390070], [159.5060666009, 46.59775507784, 2.997796852837],
                    [4.197781390070, 2.997796852837, 0.5312605269058]]
TV7_M6_EXACT = (12167.55425447, 181.0203314241, -2.028075344310)
TV7_GAMMA6_EXACT = [[2419.780106737, 158.7142786852, 4.559170510788], [158.7142786852, 45.85188385012, 3.479594717961],
                    [4.559170510788, 3.479594717961, 0.4466942604321]]
P_BAR_08 = -0.8416212335729143


def _tv7_filter(disc, zs=TV7_Z):
    f = SingerFilter1D(model(disc), 50.0, m0=np.zeros(3), P0=np.diag([2500.0, 25.0, 1.0]))
    out = [f.step(zs[n], TV7_FLAGS[n - 1], DT) for n in range(1, 7)]
    return f, out


def test_tv7_paper_six_scans():
    assert norm.ppf(1 - 0.8) == pytest.approx(P_BAR_08, rel=1e-14)
    assert tuple(p > P_BAR_08 for p in TV7_P_A[:6]) == TV7_FLAGS
    assert tuple(p > P_BAR_08 for p in TV7_P_B[:6]) == TV7_FLAGS
    f, out = _tv7_filter("paper")
    for n, (m_ref, g_ref) in enumerate(TV7_PAPER):
        assert rel(out[n].m, m_ref) <= 1e-9, n
        assert rel(np.diag(out[n].P), g_ref) <= 1e-9, n
    assert rel(f.P, TV7_GAMMA6_PAPER) <= 1e-9


def test_tv7_exact_six_scans():
    f, _ = _tv7_filter("exact")
    assert rel(f.m, TV7_M6_EXACT) <= 1e-9
    assert rel(f.P, TV7_GAMMA6_EXACT) <= 1e-9


def _tv7_oracle(disc, p_seq, zs=TV7_Z, b1_zero=False):
    F, Q = oracle_FQ(disc)
    R = np.array([[2500.0]])
    m, gamma = np.zeros(3), np.diag([2500.0, 25.0, 1.0])
    gains = []
    for n in range(6):
        phi = 1.0 if p_seq[n] > P_BAR_08 else 0.0
        xi_n, xi_next = np.array([zs[n], p_seq[n]]), np.array([zs[n + 1], p_seq[n + 1]])
        a0, a1, b1, b2, A0, A1, B1, B2 = theorem1_coefficients(F, Q, H_POS, R, phi, DT, xi_n)
        if b1_zero:
            B1 = np.zeros_like(B1)
        m, gamma, gain = thm1_step(m, gamma, a0, a1, b1, b2, A0, A1, B1, B2, DT, xi_next - xi_n)
        gains.append(gain)
    return m, gamma, gains


@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_tv7_oracle_with_fictitious_p_and_garbage_at_misses(disc):
    """R5 on TV7: sequences A and B (with z2 = z5 = -7e5 for B) give the same result; p-gain column is 0."""
    zs_b = list(TV7_Z)
    zs_b[2] = zs_b[5] = -7e5
    m_a, g_a, gains_a = _tv7_oracle(disc, TV7_P_A)
    m_b, g_b, gains_b = _tv7_oracle(disc, TV7_P_B, zs_b)
    assert rel(m_b, m_a) <= 1e-12 and rel(g_b, g_a) <= 1e-12
    for gain in gains_a + gains_b:
        assert np.all(gain[:, -1] == 0.0)
    f, _ = _tv7_filter(disc, zs_b)
    assert rel(f.m, m_a) <= 1e-9 and rel(f.P, g_a) <= 1e-9
    ref_m = TV7_PAPER[-1][0] if disc == "paper" else TV7_M6_EXACT
    ref_g = TV7_GAMMA6_PAPER if disc == "paper" else TV7_GAMMA6_EXACT
    assert rel(m_a, ref_m) <= 1e-9 and rel(g_a, ref_g) <= 1e-9


def test_tv7_exact_needs_b1_equal_phi_h_b1():
    """§3.4: with B1 = 0 under "exact" the oracle is wrong: m1(6) lower by 3.4888 m, gamma11(6) = 2577.73."""
    m_good, g_good, _ = _tv7_oracle("exact", TV7_P_A)
    m_bad, g_bad, _ = _tv7_oracle("exact", TV7_P_A, b1_zero=True)
    assert m_good[0] - m_bad[0] == pytest.approx(3.4888, abs=1e-4)
    assert g_bad[0, 0] == pytest.approx(2577.73, abs=0.01)
    # for the paper model H Q_P = 0, so B1 = 0 is exact
    m_p, g_p, _ = _tv7_oracle("paper", TV7_P_A)
    m_p0, g_p0, _ = _tv7_oracle("paper", TV7_P_A, b1_zero=True)
    np.testing.assert_array_equal(m_p, m_p0)


def _p_sequences(flags, p_bar, n_sequences, rng):
    """Several p sequences with phi(p_n) = flags[n] (p_n > p_bar iff detected); last entry free."""
    out = []
    for _ in range(n_sequences):
        u = rng.random(len(flags) + 1)
        p = np.empty(len(flags) + 1)
        hi, lo = norm.cdf(p_bar), norm.cdf(p_bar)
        for n, d in enumerate(flags):
            # inverse-CDF draw from the truncated normal on the right side of p_bar
            p[n] = norm.ppf(hi + u[n] * (1 - hi)) if d else norm.ppf(u[n] * lo)
        p[-1] = rng.standard_normal()
        out.append(p)
    return out


@pytest.mark.parametrize("measurement", ["pos", "posvel"])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r5_fictitious_p_drops_out(measurement, disc):
    rng = np.random.default_rng(5)
    n_scans, p_d, sigma, sigma_v = 60, 0.7, 80.0, 4.0
    p_bar = norm.ppf(1 - p_d)
    flags = rng.random(n_scans) < p_d
    flags[0] = True
    truth_x = 1000 + 220 * DT * np.arange(n_scans + 1) + 3 * (DT * np.arange(n_scans + 1)) ** 1.5
    truth_v = np.gradient(truth_x, DT)
    H = H_POS if measurement == "pos" else H_POSVEL
    R = np.diag([sigma**2] + ([sigma_v**2] if measurement == "posvel" else []))
    F, Q = oracle_FQ(disc)
    results = []
    z_common = truth_x + sigma * rng.standard_normal(n_scans + 1)
    vz_common = truth_v + sigma_v * rng.standard_normal(n_scans + 1)
    for p_seq in _p_sequences(flags, p_bar, 3, rng):
        z, vz = z_common.copy(), vz_common.copy()
        # arbitrary (different per sequence) values at missed scans
        z[1:][~flags] = rng.uniform(-1e6, 1e6, (~flags).sum())
        vz[1:][~flags] = rng.uniform(-1e4, 1e4, (~flags).sum())
        obs = np.column_stack([z, vz][: H.shape[0]] + [p_seq])
        steps = [dict(F=F, Q=Q, phi=float(p_seq[n] > p_bar), xi_n=obs[n], xi_next=obs[n + 1]) for n in range(n_scans)]
        m0 = np.array([z[0], vz[0] if measurement == "posvel" else 0.0, 0.0])
        P0 = np.diag([sigma**2, 30.0**2, SIGMA_A**2])
        ms, gammas, gains = thm1_run(m0, P0, steps, DT, H, R)
        for gain in gains:
            assert np.all(gain[:, -1] == 0.0)  # the p-column of the gain is exactly zero
        results.append((np.array(ms), np.array(gammas)))
        f = SingerFilter1D(model(disc), sigma, measurement, sigma_v if measurement == "posvel" else None, m0=m0, P0=P0)
        for n in range(1, n_scans + 1):
            meas = obs[n, :-1] if measurement == "posvel" else obs[n, 0]
            f.step(meas, bool(flags[n - 1]), DT)
            assert rel(f.m, ms[n - 1]) <= 1e-9 and rel(f.P, gammas[n - 1]) <= 1e-9
    for ms, gammas in results[1:]:
        for n in range(n_scans):
            assert rel(ms[n], results[0][0][n]) <= 1e-12
            assert rel(gammas[n], results[0][1][n]) <= 1e-12


# --------------------------------------------------------------------------- R11 oracles over 200+ scans


def _random_spd(rng):
    A = rng.standard_normal((3, 3)) * np.array([60.0, 6.0, 0.6])[:, None]
    return A @ A.T + np.diag([100.0, 4.0, 0.05])


def _scenario(rng, n_scans, sigma, sigma_v):
    t = DT * np.arange(n_scans + 1)
    x = 5000 + 180 * t + 400 * np.sin(t / 300.0)
    v = 180 + (400 / 300.0) * np.cos(t / 300.0)
    return x + sigma * rng.standard_normal(t.size), v + sigma_v * rng.standard_normal(t.size)


@pytest.mark.parametrize("form", ["joseph", "standard"])
@pytest.mark.parametrize("measurement", ["pos", "posvel"])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r11_filter_matches_theorem1_theorem2_and_explicit_formulas(disc, measurement, form):
    rng = np.random.default_rng({"paper": 11, "exact": 12}[disc] + {"pos": 0, "posvel": 100}[measurement])
    n_scans, sigma, sigma_v = 220, 120.0, 6.0
    flags = rng.random(n_scans) < 0.7
    z, vz = _scenario(rng, n_scans, sigma, sigma_v)
    gamma0 = _random_spd(rng)
    m0 = np.array([z[0], 150.0, 0.0])
    H = H_POS if measurement == "pos" else H_POSVEL
    R = np.diag([sigma**2] + ([sigma_v**2] if measurement == "posvel" else []))
    F, Q = oracle_FQ(disc)
    f = SingerFilter1D(model(disc), sigma, measurement, sigma_v if measurement == "posvel" else None,
                       update_form=form, m0=m0, P0=gamma0)
    m_o, g_o = m0.copy(), gamma0.copy()
    m_c, g_c = m0.copy(), gamma0.copy()
    worst = {"a_m": 0.0, "a_g": 0.0, "b_m": 0.0, "b_g": 0.0, "c_m": 0.0, "c_g": 0.0}
    for n in range(1, n_scans + 1):
        phi = float(flags[n - 1])
        meas = np.array([z[n], vz[n]])[: H.shape[0]]
        # (b) Theorem 2 against the pure extrapolation
        a0, a1, b1, b2, *_ = theorem1_coefficients(F, Q, H, R, phi, DT, np.zeros(H.shape[0] + 1))
        em_o, eg_o = thm2(f.m, f.P, a0, a1, b1, b2, DT)
        em, eg = f.extrapolate(DT)
        worst["b_m"] = max(worst["b_m"], rel(em, em_o))
        worst["b_g"] = max(worst["b_g"], rel(eg, eg_o))
        f.step(meas if measurement == "posvel" else meas[0], bool(flags[n - 1]), DT)
        # (a) Theorem 1 literally, with p appended (p values irrelevant: R5)
        xi_n = np.concatenate([np.array([z[n - 1], vz[n - 1]])[: H.shape[0]], [0.3]])
        xi_next = np.concatenate([meas, [-0.4]])
        coeffs = theorem1_coefficients(F, Q, H, R, phi, DT, xi_n)
        m_o, g_o, _ = thm1_step(m_o, g_o, *coeffs, DT, xi_next - xi_n)
        worst["a_m"] = max(worst["a_m"], rel(f.m, m_o))
        worst["a_g"] = max(worst["a_g"], rel(f.P, g_o))
        # (c) the printed scalar formulas, paper model only
        if disc == "paper":
            if measurement == "pos":
                m_c, g_c, _ = explicit_1d_pos(m_c, g_c, z[n], phi, DT, TAU, SIGMA_A, sigma)
            else:
                m_c, g_c, _ = explicit_1d_posvel(m_c, g_c, z[n], vz[n], phi, DT, TAU, SIGMA_A, sigma, sigma_v)
            worst["c_m"] = max(worst["c_m"], rel(f.m, m_c))
            worst["c_g"] = max(worst["c_g"], rel(f.P, g_c))
    assert max(worst.values()) <= 1e-9, worst


# --------------------------------------------------------------------------- R3, R4, R6


def test_r3_forms_agree_and_both_symmetrise():
    rng = np.random.default_rng(3)
    fj = SingerFilter1D(model(), 40.0, m0=M_N, P0=GAMMA_N, update_form="joseph")
    fs = SingerFilter1D(model(), 40.0, m0=M_N, P0=GAMMA_N, update_form="standard")
    for n in range(300):
        z, det = 1000 + 2000 * n + 40 * rng.standard_normal(), bool(rng.random() < 0.8)
        a, b = fj.step(z, det, DT), fs.step(z, det, DT)
        np.testing.assert_array_equal(a.P, a.P.T)
        np.testing.assert_array_equal(b.P, b.P.T)
        assert rel(a.P, b.P) <= 1e-9 and rel(a.m, b.m) <= 1e-9
    assert "update_form" in inspect.signature(SingerFilter1D).parameters
    with pytest.raises(ValueError, match="update_form"):
        SingerFilter1D(model(), 40.0, update_form="information")


def test_r3_step_returns_innovation_statistics():
    f = SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N)
    em, eg = f.extrapolate(DT)
    out = f.step(3100.0, True, DT)
    S = eg[0, 0] + 2500
    assert out.nu.shape == (1,) and out.S.shape == (1, 1) and out.K.shape == (3, 1)
    assert out.nu[0] == pytest.approx(3100 - em[0], rel=1e-14)
    np.testing.assert_allclose(out.K[:, 0], eg[:, 0] / S, rtol=1e-13)
    assert out.d2 == pytest.approx((3100 - em[0]) ** 2 / S, rel=1e-13)


@pytest.mark.parametrize("measurement", ["pos", "posvel"])
def test_r4_values_at_missed_scans_cannot_change_the_state(measurement):
    rng = np.random.default_rng(4)
    flags = rng.random(150) < 0.6
    z, vz = _scenario(rng, 150, 100.0, 5.0)
    states = []
    for variant in range(3):
        f = SingerFilter1D(model("exact"), 100.0, measurement, 5.0, m0=[z[0], 0, 0], P0=np.diag([1e4, 400, 1.0]))
        for n in range(1, 151):
            if flags[n - 1]:
                meas = [z[n], vz[n]] if measurement == "posvel" else z[n]
            else:
                junk = [None, math.nan, 1e9 * rng.standard_normal()][variant]
                meas = junk if (junk is None or measurement == "pos") else [junk, junk]
            f.step(meas, bool(flags[n - 1]), DT)
        states.append((f.m, f.P))
    for m, P in states[1:]:
        np.testing.assert_array_equal(m, states[0][0])
        np.testing.assert_array_equal(P, states[0][1])


def test_r4_no_detection_probability_parameter():
    names = set(inspect.signature(SingerFilter1D).parameters) | set(inspect.signature(SingerFilter1D.step).parameters)
    assert not any(n in names for n in ("pd", "p_d", "p_detection", "P_D"))


@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r4_r6_consecutive_misses_equal_chained_theorem2(disc):
    F, Q = oracle_FQ(disc)
    f = SingerFilter1D(model(disc), 50.0, m0=M_N, P0=GAMMA_N)
    m_o, g_o = M_N.copy(), GAMMA_N.copy()
    a0, a1, b1, b2, *_ = theorem1_coefficients(F, Q, H_POS, np.array([[2500.0]]), 0.0, DT, np.zeros(2))
    for k in range(5):
        m_pure, P_pure = f.extrapolate(DT)
        out = f.step(None, False, DT)
        # extrapolate is the same code path as step's prediction, and pure
        np.testing.assert_array_equal(out.m, m_pure)
        np.testing.assert_array_equal(out.P, P_pure)
        m_o, g_o = thm2(m_o, g_o, a0, a1, b1, b2, DT)
        assert rel(out.m, m_o) <= 1e-12 and rel(out.P, g_o) <= 1e-12


def test_r6_extrapolate_is_pure():
    f = SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N)
    m_before, P_before = f.m, f.P
    a = f.extrapolate(DT)
    b = f.extrapolate(DT)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(f.m, m_before)
    np.testing.assert_array_equal(f.P, P_before)
    assert len(f.history) == 0


def _chain(disc, steps, dt):
    f = SingerFilter1D(model(disc), 50.0, m0=M_N, P0=GAMMA_N)
    for _ in range(steps - 1):
        f.step(None, False, dt)
    return f.extrapolate(dt)


def test_tv3_r6_step_aggregation_exact_holds_paper_does_not():
    m3, P3 = _chain("exact", 3, 10.0)
    m1, P1 = _chain("exact", 1, 30.0)
    np.testing.assert_allclose(np.diag(P3), [186698.4067886, 621.8557112841, 0.8528482235314], rtol=1e-9)
    assert rel(P1, P3) <= 1e-9 and rel(m1, m3) <= 1e-9
    for k in (2, 4, 7):  # one extrapolation over k dt equals k extrapolations over dt (R6)
        assert rel(_chain("exact", 1, 7.5 * k)[1], _chain("exact", k, 7.5)[1]) <= 1e-9
    # "paper": documented non-aggregation (G7)
    _, P3p = _chain("paper", 3, 10.0)
    _, P1p = _chain("paper", 1, 30.0)
    np.testing.assert_allclose(np.diag(P3p), [182401.0291412, 600.14572784, 0.85284822353], rtol=1e-9)
    np.testing.assert_allclose(np.diag(P1p), [192400, 628, 0.85284822353], rtol=1e-9)
    assert abs(P1p[0, 0] / P3p[0, 0] - 1) > 0.05
    paper = SingerAxisModel(TAU, SIGMA_A, "paper")
    assert paper.Q(20.0)[0, 0] == 0.0
    F10, Q10 = paper.F(10.0), paper.Q(10.0)
    assert (F10 @ Q10 @ F10.T + Q10)[0, 0] == pytest.approx(708.6717235655, rel=1e-10)


# --------------------------------------------------------------------------- R10, TV-S


TVS_PAPER_M6 = (12121.42045914, 156.2748351396, -2.365667979668)
TVS_PAPER_DIAG = (2475.022420643, 264.2256471938, 7.245177765886)
TVS_PAPER_G12 = 219.1773477415
TVS_EXACT_M6 = (12110.96613159, 176.5900638138, -1.290969706057)
TVS_EXACT_DIAG = (2484.837507861, 284.1024724721, 6.432302194175)
#: TV-S prints the flags (1,1,0,1,0,1) and calls them "as TV7", whose flags are (1,0,1,1,0,1);
#: the TV-S numbers follow the printed (1,1,0,1,0,1) (checked: with TV7's flags they are off by ~5 m).
TVS_FLAGS = (True, True, False, True, False, True)


@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_tvs_switching_coefficients(disc):
    quiet, manoeuvre = SingerParams(sigma_a=1.0, tau=60.0), SingerParams(sigma_a=3.0, tau=20.0)
    switch = ManeuverSwitch(quiet, manoeuvre)
    psi = [0, 0, 0, 1, 1, 1]
    seen_lengths = []
    inner = switch.policy(psi)

    def policy(history):
        seen_lengths.append((len(history), len(history.measurements)))
        return inner(history)

    f = SingerFilter1D(model(disc), 50.0, coefficient_policy=policy, m0=np.zeros(3), P0=np.diag([2500.0, 25.0, 1.0]))
    for n in range(1, 7):
        f.step(TV7_Z[n], TVS_FLAGS[n - 1], DT)
    # non-anticipative: before step n+1 the policy sees exactly scans 1..n
    assert seen_lengths == [(k, k) for k in range(6)]
    assert f.params_used == [quiet] * 3 + [manoeuvre] * 3
    m_ref, d_ref = (TVS_PAPER_M6, TVS_PAPER_DIAG) if disc == "paper" else (TVS_EXACT_M6, TVS_EXACT_DIAG)
    assert rel(f.m, m_ref) <= 1e-9
    assert rel(np.diag(f.P), d_ref) <= 1e-9
    if disc == "paper":
        assert f.P[0, 1] == pytest.approx(TVS_PAPER_G12, rel=1e-9)
    # Theorem 1 with time-varying a1, b1 (2a)
    steps = []
    for n in range(6):
        p = quiet if psi[n] == 0 else manoeuvre
        F, Q = oracle_FQ(disc, tau=p.tau, sigma_a=p.sigma_a)
        steps.append(dict(F=F, Q=Q, phi=float(TVS_FLAGS[n]), xi_n=[TV7_Z[n], 0.0], xi_next=[TV7_Z[n + 1], 0.0]))
    ms, gammas, _ = thm1_run(np.zeros(3), np.diag([2500.0, 25.0, 1.0]), steps, DT, H_POS, np.array([[2500.0]]))
    assert rel(f.m, ms[-1]) <= 1e-9 and rel(f.P, gammas[-1]) <= 1e-9


def test_r10_explicit_params_and_records():
    f = SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N)
    p = SingerParams(sigma_a=2.0, tau=30.0)
    em, eg = f.extrapolate(DT, p)
    used = f.predict(DT, p)
    assert used == p
    np.testing.assert_array_equal(f.m, em)
    F, Q = paper_FQ(DT, 30.0, 2.0)
    assert rel(eg, F @ GAMMA_N @ F.T + Q) <= 1e-12
    f.step(5000.0, True, DT)  # default: the nominal parameters
    assert f.params_used == [SingerParams(1.0, 60.0)]
    with pytest.raises(ValueError):
        SingerParams(sigma_a=-1.0, tau=10.0)
    with pytest.raises(ValueError):
        SingerParams(sigma_a=1.0, tau=0.0)
    with pytest.raises(ValueError):
        ManeuverSwitch(SingerParams(1, 60), SingerParams(3, 20))(2)
    with pytest.raises(TypeError):
        f.step(1.0, True, DT, params=(1.0, 60.0))


# --------------------------------------------------------------------------- R13


def test_r13_paper_initialisation():
    f = SingerFilter1D(model(), 100.0, "posvel", 5.0)
    f.initialize([1234.0, 210.0])
    np.testing.assert_array_equal(f.m, [1234.0, 210.0, 0.0])
    np.testing.assert_array_equal(f.P, np.diag([1e4, 25.0, 1.0]))
    g = SingerFilter1D(model(sigma_a=2.0), 100.0)
    with pytest.raises(ValueError, match="sigma_v0"):
        g.initialize(1234.0)
    g.initialize(1234.0, sigma_v0=30.0)
    np.testing.assert_array_equal(g.m, [1234.0, 0.0, 0.0])
    np.testing.assert_array_equal(g.P, np.diag([1e4, 900.0, 4.0]))


def test_r13_steady_initialisation():
    f = SingerFilter1D(model(), 100.0)
    f.initialize(500.0, init="steady", dt=DT)
    np.testing.assert_array_equal(f.m, [500.0, 0.0, 0.0])
    assert f.P[0, 0] == pytest.approx(7789.46385, rel=1e-9)
    np.testing.assert_array_equal(f.P, steady_state(model(), "pos", sigma=100.0, dt=DT).P_filt)
    with pytest.raises(ValueError):
        f.initialize(500.0, init="steady")
    with pytest.raises(ValueError):
        f.initialize(500.0, init="random")


def test_from_parameters_defaults_to_paper():
    f = SingerFilter1D.from_parameters(60.0, 1.0, 50.0)
    assert f.model.discretization == "paper"


# --------------------------------------------------------------------------- R16 input validation


@pytest.mark.parametrize("bad_dt", [0.0, -10.0, math.nan, math.inf, "10 s"])
def test_r16_invalid_dt(bad_dt):
    f = SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N)
    with pytest.raises(ValueError, match="dt"):
        f.step(1.0, True, bad_dt)
    with pytest.raises(ValueError, match="dt"):
        f.extrapolate(bad_dt)


@pytest.mark.parametrize("bad_z", [math.nan, math.inf, None])
def test_r16_non_finite_measurement_at_detected_scan(bad_z):
    f = SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N)
    with pytest.raises(ValueError):
        f.step(bad_z, True, DT)
    g = SingerFilter1D(model(), 50.0, "posvel", 5.0, m0=M_N, P0=GAMMA_N)
    with pytest.raises(ValueError):
        g.step([1.0, math.nan], True, DT)


def test_r16_invalid_construction():
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 0.0)
    with pytest.raises(ValueError):
        SingerFilter1D(model(), math.nan)
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, "velocity")
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, "posvel")  # sigma_v missing
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, m0=[0, 0, math.nan], P0=GAMMA_N)
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N + np.triu(np.ones((3, 3)), 1))
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, m0=M_N, P0=-GAMMA_N)
    with pytest.raises(ValueError, match="not initialised"):
        SingerFilter1D(model(), 50.0).step(1.0, True, DT)
    with pytest.raises(ValueError):
        SingerFilter1D(model(), 50.0, m0=M_N, P0=GAMMA_N).step(1.0, 2, DT)
