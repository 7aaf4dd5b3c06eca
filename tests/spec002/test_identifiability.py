"""Spec 002 R5-R9: the identifiability checker on TV1 (paper example), TV2 (local vs global, rounding
zero, G5), TV5 (unit invariance), TV6 (window, G6) and the explicit-S rows of TV8 (D, m < p, weak).
Exact-arithmetic cases at 1e-12 relative (spec §5), printed decimals at their last digit, TV8's κ at 1 %."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.analysis.identifiability import (
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    check_identifiability,
)
from skytrack.analysis.identifiability_sequence import check_sequence, summarize

EXACT = 1e-12
#: §3.5: h measures x1 and x5, the parameters are a1 = x5, a2 = x6
H_PAPER = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0]])
H_A = np.array([[0.0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]])
#: TV3's F (f15 = 2, f16 = 3)
F_TV3 = np.array(
    [
        [1, 0.5, 0, 0, 2, 3],
        [0, 1, 0.1, 0, 0.5, 0.7],
        [0, 0, 1, 0.1, 0.2, 0],
        [0, 0, 0, 1, 0, 0.4],
        [0, 0, 0, 0, 1, 0],
        [0, 0, 0, 0, 0, 1.0],
    ]
)


def paper_F(f15: float, f16: float, rng: np.random.Generator) -> np.ndarray:
    """§3.5's F: columns 5 and 6 as printed (f25, f35, f26, f46 free), columns 1-4 arbitrary."""
    F = rng.normal(size=(6, 6))
    F[:, 4] = [f15, rng.normal(), rng.normal(), 0, 1, 0]
    F[:, 5] = [f16, rng.normal(), 0, rng.normal(), 0, 1]
    return F


# ---------------------------------------------------------------- TV1


TV1 = [
    # f15, f16, S, det, κ, verdict, Z of a2, σ_χ
    (2, 3, [[2, 3], [1, 0]], 9, math.sqrt(5) - 2, "identifiable", False, (1, 0.7453559925)),
    (2, -1, [[2, -1], [1, 0]], 1, math.sqrt(5) - 2, "identifiable", False, (1, 2.2360679775)),
    (2, 0, [[2, 0], [1, 0]], 0, 0, "not_identifiable", True, None),
    (0, 1e-3, [[0, 1e-3], [1, 0]], 1e-6, 1, "identifiable", False, (1, 1000)),
]


def tv1_checks(method="svd"):
    rng = np.random.default_rng(2)
    F = np.stack([paper_F(row[0], row[1], rng) for row in TV1])
    return check_identifiability(H=H_PAPER, F=F, h_a=H_A, noise_cov=np.eye(2), method=method)


def test_tv1_table_batched_over_the_four_rows():
    checks = tv1_checks()
    for i, (_, _, S, det, kappa, verdict, a2_zero, sigma_chi) in enumerate(TV1):
        np.testing.assert_allclose(checks.sensitivity[i], S, rtol=EXACT, atol=0)
        assert checks.det[i] == pytest.approx(det, rel=EXACT, abs=1e-300)
        assert checks.kappa[i] == pytest.approx(kappa, rel=1e-10, abs=1e-15)
        assert checks.verdicts[i] == verdict
        assert checks.zero_influence_names(i) == (["a2"] if a2_zero else [])
        assert checks.indistinguishable_names(i) == []
        if sigma_chi is None:
            assert np.isnan(checks.precision[i]).all()
        else:
            np.testing.assert_allclose(checks.precision[i], sigma_chi, rtol=1e-10)
    assert checks.messages(2) == ["parameter a2 has no influence on the measurements over [t_2, t_3]"]
    assert checks.messages(0) == []


def test_tv1_literal_det_fails_only_for_f16_zero():
    checks = tv1_checks(method="det")
    assert checks.verdicts == ["identifiable", "identifiable", "not_identifiable", "identifiable"]
    # the culprit analysis is still reported under the literal method
    assert checks.zero_influence_names(2) == ["a2"]


def test_tv1_symbolic_identity_on_random_values():
    """M = [[f15²+1, f15 f16], [f15 f16, f16²]], det M = f16², and σ_χ = rows of L = [[0, 1], [1/f16, −f15/f16]]."""
    rng = np.random.default_rng(7)
    f15 = rng.uniform(-5, 5, size=50)
    f16 = rng.uniform(0.1, 5, size=50) * rng.choice([-1, 1], size=50)
    F = np.stack([paper_F(a, b, rng) for a, b in zip(f15, f16)])
    checks = check_identifiability(H=H_PAPER, F=F, h_a=H_A, noise_cov=np.eye(2))
    S = checks.sensitivity
    M = np.swapaxes(S, -1, -2) @ S
    np.testing.assert_allclose(M[:, 0, 0], f15**2 + 1, rtol=EXACT)
    np.testing.assert_allclose(M[:, 0, 1], f15 * f16, rtol=EXACT)
    np.testing.assert_allclose(M[:, 1, 1], f16**2, rtol=EXACT)
    np.testing.assert_allclose(checks.det, f16**2, rtol=1e-10)
    L_rows = np.stack([np.ones_like(f16), np.sqrt(1 + f15**2) / np.abs(f16)], axis=1)
    np.testing.assert_allclose(checks.precision, L_rows, rtol=1e-10)
    # κ does not depend on f16: the columns' angle is fixed by f15 (TV1 note)
    F_scaled = F.copy()
    F_scaled[:, 0, 5] *= 17.0
    rescaled = check_identifiability(H=H_PAPER, F=F_scaled, h_a=H_A, noise_cov=np.eye(2))
    np.testing.assert_allclose(rescaled.kappa, checks.kappa, rtol=1e-10)
    assert (checks.verdict_code == IDENTIFIABLE).all()


# ---------------------------------------------------------------- TV2


COS = (
    0.7071067811865476,
    6.123233995736766e-17,
    -0.7071067811865475,
    -1.0,
    -0.7071067811865477,
    -1.8369701987210297e-16,
    0.7071067811865474,
    1.0,
)


def tv2_F(c=COS) -> np.ndarray:
    F = np.repeat(F_TV3[None], len(c), axis=0)
    F[:, 0, 4] = 1.0
    F[:, 0, 5] = c
    return F


def test_tv2_local_and_global_with_svd_method():
    seq = check_sequence(H_PAPER, tv2_F(), H_A, noise_cov=np.eye(2))
    assert seq.steps.tolist() == list(range(1, 9))
    expected = ["not_identifiable" if k in (2, 6) else "identifiable" for k in range(1, 9)]
    assert seq.verdicts == expected
    for i, k in enumerate(seq.steps):
        if k in (2, 6):
            assert seq.checks.zero_influence_names(i) == ["a2"]
            assert seq.checks.kappa[i] == 0
        else:
            assert seq.checks.kappa[i] == pytest.approx(0.414213562373095, rel=EXACT)
    assert seq.global_verdict == "not_identifiable"
    assert seq.failing_steps == [2, 6]
    assert seq.zero_influence_count == {"a1": 0, "a2": 2}
    assert seq.indistinguishable_count == {"a1": 0, "a2": 0}
    assert seq.messages() == [
        "k = 2: parameter a2 has no influence on the measurements over [t_1, t_2]",
        "k = 6: parameter a2 has no influence on the measurements over [t_5, t_6]",
    ]


def test_tv2_literal_det_passes_the_rounding_zeros():
    seq = check_sequence(H_PAPER, tv2_F(), H_A, noise_cov=np.eye(2), method="det", det_tol=0.0)
    assert seq.checks.det[1] == pytest.approx(3.749399456654644e-33, rel=EXACT)
    assert seq.checks.det[5] == pytest.approx(3.3744595109891873e-32, rel=EXACT)
    assert seq.verdicts == ["identifiable"] * 8
    assert seq.global_verdict == "identifiable"
    # the culprit analysis still names a2 at k = 2, 6 (G5)
    assert seq.zero_influence_count == {"a1": 0, "a2": 2}


@pytest.mark.parametrize("method", ["svd", "det"])
def test_tv2_exact_zeros_fail_with_both_methods(method):
    c = list(COS)
    c[1] = c[5] = 0.0
    seq = check_sequence(H_PAPER, tv2_F(tuple(c)), H_A, noise_cov=np.eye(2), method=method)
    assert seq.failing_steps == [2, 6]
    assert seq.global_verdict == "not_identifiable"


# ---------------------------------------------------------------- TV5


@pytest.mark.parametrize(
    "scale, det, raw_ratio, last_digit",
    [(1.0, 9.0, 0.22515, 1e-5), (1e-3, 9e-6, 6.0e-4, 1e-5), (1e3, 9e6, 3.3e-4, 1e-5)],
)
def test_tv5_kappa_is_unit_invariant_det_and_raw_ratio_are_not(scale, det, raw_ratio, last_digit):
    S = np.array([[2.0, 3.0 * scale], [1.0, 0.0]])
    checks = check_identifiability(S)
    assert checks.det[0] == pytest.approx(det, rel=EXACT)
    assert checks.raw_sigma_ratio[0] == pytest.approx(raw_ratio, abs=last_digit / 2)
    assert checks.kappa[0] == pytest.approx(math.sqrt(5) - 2, rel=1e-10)
    assert checks.verdicts == ["identifiable"]


def test_tv5_param_scale_and_measurement_units_leave_kappa_and_verdict_unchanged():
    """d rescales the parameters, V_η = diag(u²) with S's rows × u changes measurement units: κ fixed,
    σ_χ in parameter units scales with d only through the change of unit."""
    S = np.array([[2.0, 3.0], [1.0, 0.0]])
    base = check_identifiability(S, noise_cov=np.eye(2))
    u = np.array([1e3, 0.5])
    rescaled = check_identifiability(
        u[:, None] * S * np.array([1.0, 1e-3]), noise_cov=np.diag(u**2), param_scale=[1.0, 1e3]
    )
    assert rescaled.kappa[0] == pytest.approx(base.kappa[0], rel=1e-10)
    assert rescaled.verdicts == base.verdicts == ["identifiable"]
    # column 2 of S is now per 1e-3 of the old unit, so χ2 is 1e3 times larger in the new unit
    np.testing.assert_allclose(rescaled.precision[0], base.precision[0] * [1.0, 1e3], rtol=1e-10)


# ---------------------------------------------------------------- TV6


def test_tv6_two_step_window_reveals_a2():
    F = F_TV3.copy()
    F[0, 5] = 0.0
    F_seq = np.stack([F, F])
    one = check_sequence(H_PAPER, F_seq, H_A, noise_cov=np.eye(2), window=1)
    np.testing.assert_allclose(one.checks.sensitivity[0], [[2, 0], [1, 0]], rtol=EXACT)
    assert one.verdicts == ["not_identifiable"] * 2
    assert one.checks.zero_influence_names(0) == ["a2"]
    two = check_sequence(H_PAPER, F_seq, H_A, noise_cov=np.eye(2), window=2)
    np.testing.assert_allclose(two.checks.sensitivity[0], [[2, 0], [1, 0], [4.25, 0.35], [1, 0]], rtol=EXACT)
    assert two.verdicts == ["identifiable"]
    assert two.checks.kappa[0] == pytest.approx(0.2675472390, abs=5e-11)
    assert two.steps.tolist() == [1]


def test_tv6_window_agrees_with_finite_differences_of_two_measurements():
    """S⁽²⁾ = ∂(y(k), y(k+1))/∂χ with x(k) = F(x(k−1) + h_aᵀw), noise-free."""
    F = F_TV3.copy()
    F[0, 5] = 0.0
    x0 = np.array([1, 2, 3, 4, 0.5, -0.2])

    def measurements(chi):
        x = x0.copy()
        x[4:] = chi
        x1 = F @ x
        return np.concatenate([H_PAPER @ x1, H_PAPER @ (F @ x1)])

    step = 1e-6
    columns = [
        (measurements(x0[4:] + step * e) - measurements(x0[4:] - step * e)) / (2 * step) for e in np.eye(2)
    ]
    window = check_sequence(H_PAPER, np.stack([F, F]), H_A, window=2)
    np.testing.assert_allclose(window.checks.sensitivity[0], np.stack(columns, axis=1), atol=1e-8)


def test_window_uses_block_diagonal_noise_of_each_step():
    """Step k+1 with 4× the noise: whitening divides its rows by 2 (R8's block-diagonal V_η)."""
    F = F_TV3.copy()
    F[0, 5] = 0.0
    cov = np.stack([np.eye(2), 4 * np.eye(2)])
    seq = check_sequence(H_PAPER, np.stack([F, F]), H_A, noise_cov=cov, window=2)
    S = np.array([[2, 0], [1, 0], [2.125, 0.175], [0.5, 0]])
    expected = check_identifiability(S)
    assert seq.checks.kappa[0] == pytest.approx(expected.kappa[0], rel=1e-10)


def test_unknown_all_checks_the_whole_state():
    """unknown="all" puts F_k in place of G_k (G3): one step of (x1, x5) cannot fix six states."""
    seq = check_sequence(H_PAPER, np.stack([F_TV3]), unknown="all", noise_cov=np.eye(2))
    assert seq.checks.names == ("x1", "x2", "x3", "x4", "x5", "x6")
    assert seq.checks.sensitivity.shape == (1, 2, 6)
    assert seq.verdicts == ["not_identifiable"]
    assert seq.checks.fewer_channels[0]
    assert "only 2 measurement channels for 6 parameters" in seq.checks.messages(0)


# ---------------------------------------------------------------- TV8 rows with explicit S (D, m < p, weak)

RADAR_COV = np.diag([50.0**2, 50.0**2, 1.0])
OMEGA_TANGENTIAL = np.array([-100.0, 0.0, -199.99111155553362])


def test_tv8_omega_and_doppler_bias_tangential_is_weak_with_D():
    S = np.stack([OMEGA_TANGENTIAL, [0.0, 0.0, 1.0]], axis=1)
    checks = check_identifiability(S, noise_cov=RADAR_COV, names=["ω", "b_ṙ"])
    assert checks.verdicts == ["weak"]
    assert checks.kappa[0] == pytest.approx(0.005000, rel=0.01)
    assert checks.indistinguishable_names(0) == ["ω", "b_ṙ"]
    assert checks.zero_influence_names(0) == []
    # the null vector in parameter units: a Doppler bias of 200 m/s per rad/s of ω leaves ṙ unchanged
    (vector,) = checks.null_vectors_of(0).T
    assert vector[1] / vector[0] == pytest.approx(199.99111155553362, rel=1e-3)
    # R6 wording; the coefficients are the null vector in parameter units (ω column norm ≈ 200.01)
    assert checks.messages(0) == [
        "parameters ω, b_ṙ act on the measurements in (nearly) the same way; "
        "the combination 0.003536·ω + 0.7071·b_ṙ is not determined"
    ]
    assert not np.isnan(checks.precision[0]).any()


def test_tv8_doppler_only_fewer_channels_than_parameters():
    S = np.array([[OMEGA_TANGENTIAL[2], 1.0]])
    checks = check_identifiability(S, noise_cov=np.eye(1), names=["ω", "b_ṙ"])
    assert checks.verdicts == ["not_identifiable"]
    assert checks.fewer_channels[0]
    assert checks.indistinguishable_names(0) == ["ω", "b_ṙ"]
    assert "only 1 measurement channels for 2 parameters" in checks.messages(0)
    assert np.isnan(checks.precision[0]).all()


@pytest.mark.parametrize(
    "doppler_row, kappa",
    [((1.0, 0.0), 1.0), ((0.9999555577776681, 0.009999629646912757), 0.414254)],
)
def test_tv8_accelerations_pos_plus_doppler(doppler_row, kappa):
    S = np.array([[0.5, 0.0], [0.0, 0.5], doppler_row])
    checks = check_identifiability(S, noise_cov=RADAR_COV, names=["a_x", "a_y"])
    assert checks.verdicts == ["identifiable"]
    assert checks.kappa[0] == pytest.approx(kappa, rel=0.01)


def test_summary_of_direct_checks_global_is_worst():
    S = np.stack(
        [
            np.array([[2.0, 3.0], [1.0, 0.0]]),
            np.array([[1.0, 1.0], [1.0, 1.0 + 1e-4]]),
            np.array([[1.0, 0.0], [0.0, 1.0]]),
        ]
    )
    seq = summarize(check_identifiability(S))
    assert seq.verdicts == ["identifiable", "weak", "identifiable"]
    assert seq.global_verdict == "weak"
    assert seq.failing_steps == [] and seq.weak_steps == [2]
    assert seq.indistinguishable_count == {"a1": 1, "a2": 1}
    assert seq.checks.verdict_code[1] != NOT_IDENTIFIABLE


# ---------------------------------------------------------------- TV9 (R8 full state, G3)

TV9_NAMES = ("x", "y", "v_x", "v_y", "a_x", "a_y", "b_x")


def tv9_sequence(channels: tuple[str, ...], window: int):
    """R3 dynamics (T = 1) for (x, y, v_x, v_y, a_x, a_y, b_x) from p = (30 000, 0) m, v = (0, 200) m/s;
    radar position measures (x + b_x, y) σ 50 m, ṙ σ 1 m/s (sensor at the origin), ADS-B (x, y) σ 10 m;
    H_k at the true x(k) = φ(x(k−1)), steps k = 1 … 10."""
    F = np.eye(7)
    for axis in range(2):
        F[axis, 2 + axis] = 1.0
        F[axis, 4 + axis] = 0.5
        F[2 + axis, 4 + axis] = 1.0
    states = [np.array([30_000.0, 0, 0, 200, 0, 0, 0])]
    for _ in range(10):
        states.append(F @ states[-1])
    states = np.array(states[1:])
    p, v = states[:, :2], states[:, 2:4]
    r = np.linalg.norm(p, axis=1)
    u = p / r[:, None]
    range_rate = np.einsum("ki,ki->k", u, v)
    rows, sigmas = [], []
    if "pos" in channels:
        radar = np.zeros((10, 2, 7))
        radar[:, 0, 0] = radar[:, 0, 6] = radar[:, 1, 1] = 1.0
        rows.append(radar)
        sigmas += [50.0, 50.0]
    if "rdot" in channels:
        doppler = np.zeros((10, 1, 7))
        doppler[:, 0, :2] = (v - range_rate[:, None] * u) / r[:, None]
        doppler[:, 0, 2:4] = u
        rows.append(doppler)
        sigmas += [1.0]
    if "adsb" in channels:
        adsb = np.zeros((10, 2, 7))
        adsb[:, 0, 0] = adsb[:, 1, 1] = 1.0
        rows.append(adsb)
        sigmas += [10.0, 10.0]
    H = np.concatenate(rows, axis=1)
    cov = np.diag(np.square(sigmas))
    return check_sequence(
        H, np.repeat(F[None], 10, axis=0), unknown="all", names=TV9_NAMES, noise_cov=cov, window=window
    )


@pytest.mark.parametrize("window", [3, 10])
def test_tv9_radar_position_cannot_separate_position_and_bias(window):
    seq = tv9_sequence(("pos",), window)
    assert seq.verdicts[0] == "not_identifiable"
    assert seq.checks.indistinguishable_names(0) == ["x", "b_x"]
    assert seq.checks.zero_influence_names(0) == []
    (vector,) = seq.checks.null_vectors_of(0).T
    assert vector[6] == pytest.approx(-vector[0], rel=1e-9)
    # 2 rows per step: N_w = 3 still has 6 rows for 7 states (the spec's "N_w ≤ 2" is one short)
    message, *rest = seq.checks.messages(0)
    assert rest == (["only 6 measurement channels for 7 parameters"] if window == 3 else [])
    assert message.startswith("parameters x, b_x act on the measurements in (nearly) the same way; the combination −")
    terms = message.split("the combination ")[1].removesuffix(" is not determined").split(" ")
    assert [t.split("·")[1] for t in terms if "·" in t] == ["x", "b_x"]


def test_tv9_doppler_makes_it_only_weak_and_adsb_identifiable():
    doppler = tv9_sequence(("pos", "rdot"), 10)
    assert doppler.verdicts[0] == "weak"
    assert doppler.checks.kappa[0] == pytest.approx(2.7e-4, abs=5e-6)
    assert doppler.checks.indistinguishable_names(0) == ["x", "b_x"]
    adsb = tv9_sequence(("pos", "adsb"), 10)
    assert adsb.verdicts[0] == "identifiable"
    assert adsb.checks.kappa[0] == pytest.approx(0.049, abs=5e-4)
    assert adsb.checks.indistinguishable_names(0) == []


def test_tv8_radial_omega_with_doppler_only_is_an_exactly_zero_S():
    """With only S given and p = 1 (R5 step 2 fallback) only an exactly zero column is detected."""
    checks = check_identifiability(np.zeros((1, 1)), noise_cov=np.eye(1), names=["ω"])
    assert checks.verdicts == ["not_identifiable"]
    assert checks.zero_influence_names(0) == ["ω"]
    assert checks.indistinguishable_names(0) == []
    assert checks.messages(0) == ["parameter ω has no influence on the measurements over [t_0, t_1]"]
    tiny = check_identifiability(np.array([[1e-30]]), noise_cov=np.eye(1), names=["ω"])
    assert tiny.verdicts == ["identifiable"]
