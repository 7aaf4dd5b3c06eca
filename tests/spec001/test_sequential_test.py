"""Spec 001 R2-R6, R8: the sequential pair test on TV-3 and TV-4 (tolerance 1e-6)."""

import warnings

import numpy as np
import pytest

from skytrack.identify.model import cv_model
from skytrack.identify.sequential import DIFFERENT, INSUFFICIENT, SAME, SequentialPairTest
from skytrack.identify.single_shot import track_states_test
from skytrack.identify.threshold import Threshold

PRIOR = dict(init="prior", x0=[1000.0, 2000.0, 0.0, 0.0], P0=np.diag([1000.0 ** 2, 1000.0 ** 2, 200.0 ** 2, 200.0 ** 2]),
             t0=0.0)

# TV-3a: case, q -> Q_Jeta, Q_Jxi, Q_eta, Q_xi, Lambda
TV3A = {
    ("same", 0): (7.131005, 3.592580, 4.629800, 3.947500, 2.146285),
    ("diff", 0): (42.594312, 9.605811, 4.629800, 3.947500, 43.622824),
    ("same", 25): (7.112037, 3.553727, 4.618898, 3.889642, 2.157224),
    ("diff", 25): (42.480113, 9.649120, 4.618898, 3.889642, 43.620694),
}


def _run(tv3, case, q, **kwargs):
    test = SequentialPairTest(cv_model(2, q), **kwargs)
    history = test.run(*tv3(case))
    return test, history


@pytest.mark.parametrize("case,q", sorted(TV3A))
def test_tv3a_four_forms(tv3, case, q):
    test, _ = _run(tv3, case, q)
    forms = test.forms()
    got = (forms.joint_eta[0], forms.joint_xi[0], forms.eta[0], forms.xi[0], forms.statistic[0])
    np.testing.assert_allclose(got, TV3A[(case, q)], atol=1e-6)
    assert forms.dof[0] == 4
    np.testing.assert_allclose(forms.joint_eta + forms.joint_xi, test.joint.J, atol=1e-9)  # J_joint


def test_tv3b_lambda_after_every_report(tv3):
    _, same = _run(tv3, "same", 0.0)
    _, diff = _run(tv3, "diff", 0.0)
    np.testing.assert_allclose([f.statistic[0] for f in same],
                               [0, 0, 0.628432, 2.975266, 2.486850, 1.138368, 3.499557, 2.146285], atol=1e-6)
    np.testing.assert_allclose([f.statistic[0] for f in diff],
                               [0, 0, 13.623027, 21.332392, 38.191251, 36.745507, 44.228133, 43.622824], atol=1e-6)
    assert [int(f.dof[0]) for f in same] == [0, 0, 2, 4, 4, 4, 4, 4]
    joint = np.array([f.joint_eta[0] + f.joint_xi[0] for f in same])
    np.testing.assert_allclose(np.diff(np.r_[0.0, joint]),
                               [0, 0, 0.628432, 2.346833, 2.733051, 0.811935, 3.769522, 0.433811], atol=1e-6)


def test_tv3_gls_and_prior_limit(tv3):
    """Diffuse J equals the batch GLS residual; prior mode tends to it as P0 grows (R3 checks)."""
    time, system, z, V = tv3("same")
    # batch GLS on the joint stream, reference epoch t_ref = -5 s (any epoch gives the same value)
    t_ref = -5.0
    rows = [np.hstack([np.eye(2), (t - t_ref) * np.eye(2)]) for t in time]
    H = np.vstack(rows)
    W = np.linalg.inv(np.kron(np.eye(1), np.eye(1)) * 1.0 * np.block(
        [[V[i] if i == j else np.zeros((2, 2)) for j in range(8)] for i in range(8)]))
    zz = z.reshape(-1)
    x = np.linalg.solve(H.T @ W @ H, H.T @ W @ zz)
    gls = (zz - H @ x) @ W @ (zz - H @ x)
    test, _ = _run(tv3, "same", 0.0)
    assert test.joint.J[0] == pytest.approx(gls, abs=1e-6)
    # covariance KF from x0 = 0, P0 = kappa diag(1, 1, 0.01, 0.01): Lambda(kappa = 1e12) = 2.1462787
    big, _ = _run(tv3, "same", 0.0, init="prior", x0=np.zeros(4), P0=1e12 * np.diag([1, 1, 0.01, 0.01]), t0=0.0)
    assert big.statistic[0] == pytest.approx(2.1462787, abs=1e-6)
    big, _ = _run(tv3, "diff", 0.0, init="prior", x0=np.zeros(4), P0=1e12 * np.diag([1, 1, 0.01, 0.01]), t0=0.0)
    assert big.statistic[0] == pytest.approx(43.6228174, abs=1e-6)


def test_tv3c_r8_identity_and_fused_state(tv3):
    """R8: Lambda = (x_eta - x_xi)^T (P_eta + P_xi)^-1 (x_eta - x_xi) at a common time; joint = fused (24)."""
    from skytrack.identify.single_shot import fuse_information

    for case, expected in (("same", 2.146285), ("diff", 43.622824)):
        test, _ = _run(tv3, case, 0.0)
        rows = np.array([0])
        x_eta, P_eta = test.eta.estimate_at(rows, 3.3)
        x_xi, P_xi = test.xi.estimate_at(rows, 3.3)
        assert track_states_test(x_eta, P_eta, x_xi, P_xi)[0] == pytest.approx(expected, abs=1e-6)
    test, _ = _run(tv3, "same", 0.0)
    x_eta, P_eta = test.eta.estimate_at(rows, 3.3)
    x_xi, P_xi = test.xi.estimate_at(rows, 3.3)
    np.testing.assert_allclose(x_eta[0], [1368.4, 1885.55, 113.0, -31.5], atol=1e-9)
    np.testing.assert_allclose(np.diag(P_eta[0]), [2245, 2245, 500, 500], atol=1e-9)
    np.testing.assert_allclose(x_xi[0], [1317.1, 1835.2, 90.9, -55.7], atol=1e-9)
    np.testing.assert_allclose(np.diag(P_xi[0]), [280, 280, 80, 80], atol=1e-9)
    fused, fused_too, C_inv = fuse_information(x_eta, P_eta, x_xi, P_xi)
    expected = [1322.8452016034, 1840.9417590191, 93.5964395190, -52.5825277057]
    for x in (fused[0], fused_too[0], test.joint.x[0]):
        np.testing.assert_allclose(x, expected, atol=1e-6)
    for P in (C_inv[0], test.joint.P[0]):
        np.testing.assert_allclose(np.diag(P), [248.6677670361] * 2 + [68.3800990332] * 2, atol=1e-6)


def test_tv3c_process_noise_joint_is_more_cautious_than_information_fusion(tv3):
    """R14: for q = 25, P_joint - P_fused >= 0 with eigenvalues {0.16155 x2, 10.04404 x2}."""
    from skytrack.identify.single_shot import fuse_information

    test, _ = _run(tv3, "same", 25.0)
    rows = np.array([0])
    x_eta, P_eta = test.eta.estimate_at(rows, 3.3)
    x_xi, P_xi = test.xi.estimate_at(rows, 3.3)
    fused, _, P_fused = fuse_information(x_eta, P_eta, x_xi, P_xi)
    np.testing.assert_allclose(fused[0], [1322.890276, 1841.282715, 93.838710, -51.615872], atol=1e-6)
    np.testing.assert_allclose(np.diag(P_fused[0]), [250.597191] * 2 + [85.408768] * 2, atol=1e-6)
    np.testing.assert_allclose(test.joint.x[0], [1322.916772, 1841.328132, 93.789814, -51.774493], atol=1e-6)
    np.testing.assert_allclose(np.diag(test.joint.P[0]), [251.795210] * 2 + [94.416331] * 2, atol=1e-6)
    np.testing.assert_allclose(np.linalg.eigvalsh(test.joint.P[0] - P_fused[0]),
                               [0.16155, 0.16155, 10.04404, 10.04404], atol=1e-5)


# TV-4: case, q -> Lambda, D, ln BF, P(same | 0.5), P(same | 0.1)
TV4 = {
    ("same", 0): (1.810196, -22.937858, 10.563831, 0.9999742, 0.9997676),
    ("diff", 0): (43.303269, -22.937858, -10.182705, 3.781733e-5, 4.202067e-6),
    ("same", 25): (1.821741, -22.936647, 10.557453, 0.9999740, 0.9997661),
    ("diff", 25): (43.303458, -22.936647, -10.183405, 3.779086e-5, 4.199126e-6),
}


@pytest.mark.parametrize("case,q", sorted(TV4))
def test_tv4_posterior_prior_mode(tv3, case, q):
    lam, D, log_bf, p_half, p_tenth = TV4[(case, q)]
    test, _ = _run(tv3, case, q, **PRIOR)
    assert test.statistic[0] == pytest.approx(lam, abs=1e-6)
    assert test.logdet_difference[0] == pytest.approx(D, abs=1e-6)
    assert test.log_odds(0.5)[0] == pytest.approx(log_bf, abs=1e-6)
    assert test.posterior(0.5)[0] == pytest.approx(p_half, rel=1e-6)
    assert test.posterior(0.1)[0] == pytest.approx(p_tenth, rel=1e-6)


def test_tv4_prior_mode_equals_batch_log_density(tv3):
    """ln BF = ln N(stack; joint) - ln N(eta; own) - ln N(xi; own), each a batch Gaussian log-density."""
    from scipy.stats import multivariate_normal

    time, system, z, V = tv3("same")
    x0, P0 = np.array(PRIOR["x0"]), PRIOR["P0"]

    def log_density(sel):
        H = np.vstack([np.hstack([np.eye(2), t * np.eye(2)]) for t in time[sel]])
        R = np.zeros((2 * sel.sum(),) * 2)
        for i, v in enumerate(V[sel]):
            R[2 * i:2 * i + 2, 2 * i:2 * i + 2] = v
        return multivariate_normal(H @ x0, H @ P0 @ H.T + R).logpdf(z[sel].reshape(-1))

    everything = np.ones(8, bool)
    expected = log_density(everything) - log_density(system == 1) - log_density(system == 2)
    test, _ = _run(tv3, "same", 0.0, **PRIOR)
    assert test.log_odds(0.5)[0] == pytest.approx(expected, abs=1e-6)


def test_tv4_literal_posterior_warns_and_is_miscalibrated(tv3):
    test, _ = _run(tv3, "same", 0.0, **PRIOR)
    with pytest.warns(UserWarning, match="not a calibrated"):
        literal = test.posterior(0.5, include_logdet=False)
    assert literal[0] == pytest.approx(0.288004, abs=1e-6)


def test_tv4_density_mode(tv3):
    beta = 1.0 / (1e4 * 1e4 * 400.0 * 400.0)
    for case, log_bf, p in (("same", 12.696989, 0.9999969397), ("diff", -8.041281, 3.217929e-4)):
        test, _ = _run(tv3, case, 0.0)
        half_logdet = 0.5 * np.linalg.slogdet(2 * np.pi * test.separate_covariance_sum())[1]
        assert half_logdet == pytest.approx(16.633479, abs=1e-6)
        # independent of the common time
        assert 0.5 * np.linalg.slogdet(2 * np.pi * test.separate_covariance_sum(t=-2.0))[1] == pytest.approx(
            16.633479, abs=1e-6)
        assert test.log_odds(0.5, object_density=beta)[0] == pytest.approx(log_bf, abs=1e-6)
        assert test.posterior(0.5, object_density=beta)[0] == pytest.approx(p, rel=1e-6)
    with pytest.raises(ValueError, match="object_density"):
        test.posterior(0.5)


def test_tv4_density_mode_is_the_limit_of_prior_mode(tv3):
    """Prior at the fused estimate with P0 = k diag(1e6, 1e6, 1e4, 1e4): ln BF difference 9.5e-4 ... 9.5e-8."""
    from scipy.stats import multivariate_normal

    diffuse, _ = _run(tv3, "same", 0.0)
    fused = diffuse.joint.x[0]
    # the fused state is at t = 3.3; the prior is at t0 = 0 -> take it back along the model (Q = 0)
    F_back = cv_model(2, 0.0).F(np.array([3.3]))[0]
    x0 = np.linalg.solve(F_back, fused)
    for k, expected in ((1e2, 9.5e-4), (1e4, 9.5e-6), (1e6, 9.5e-8)):
        P0 = k * np.diag([1e6, 1e6, 1e4, 1e4])
        prior, _ = _run(tv3, "same", 0.0, init="prior", x0=x0, P0=P0, t0=0.0)
        beta = multivariate_normal(x0, P0).pdf(x0)
        difference = prior.log_odds(0.5)[0] - diffuse.log_odds(0.5, object_density=beta)[0]
        assert difference == pytest.approx(expected, rel=0.06)


def test_r5_decisions_and_thresholds(tv3):
    test, history = _run(tv3, "diff", 0.0)
    decision, h = test.decide(Threshold(p_correct=0.99))
    assert decision[0] == DIFFERENT and h[0] == pytest.approx(13.276704, abs=1e-6)
    same, _ = _run(tv3, "same", 0.0)
    assert same.decide(Threshold(p_correct=0.99))[0][0] == SAME
    assert same.decide(2.0)[0][0] == DIFFERENT  # fixed h below Lambda = 2.146
    early = SequentialPairTest(cv_model(2, 0.0))
    time, system, z, V = tv3("same")
    early.run(time[:2], system[:2], z[:2], V[:2])
    assert early.decide(Threshold(p_correct=0.99))[0][0] == INSUFFICIENT


def test_r15_joint_only_statistic(tv3):
    test, _ = _run(tv3, "same", 0.0, statistic="joint-only")
    assert test.statistic[0] == pytest.approx(10.723585, abs=1e-6)
    assert test.dof[0] == 16 - 4


def test_errors_name_the_report():
    test = SequentialPairTest(cv_model(2, 1.0))
    test.add(1, 1.0, [0.0, 0.0], np.eye(2))
    with pytest.raises(ValueError, match="report 1: the measurement has NaN"):
        test.add(1, 2.0, [np.nan, 0.0], np.eye(2))
    with pytest.raises(ValueError, match="singular"):
        test.add(1, 2.0, [0.0, 0.0], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="unknown system 3"):
        test.add(3, 2.0, [0.0, 0.0], np.eye(2))
    with pytest.raises(ValueError, match="time goes backwards"):
        test.add(1, 0.5, [0.0, 0.0], np.eye(2))


def test_batched_pairs_equal_single_pairs(tv3):
    """Rows of one test are independent: two pairs at once give each pair's own values."""
    both = SequentialPairTest(cv_model(2, 25.0), 2)
    time, system, z_same, V = tv3("same")
    _, _, z_diff, _ = tv3("diff")
    for i in np.lexsort((system, time)):
        both.add(int(system[i]), time[i], np.stack([z_same[i], z_diff[i]]), V[i])
    np.testing.assert_allclose(both.statistic, [2.157224, 43.620694], atol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert both.forms().dof.tolist() == [4, 4]


def test_r5_design_separation_modes_on_tv5():
    """R5: lambda_d from a state difference or a minimum separation (TV-5b, +100 m: h = 14.881644)."""
    # TV-5a separate covariances at t = 9.3, per axis [[pos, pos-vel], [pos-vel, vel]]
    radar = np.array([[948.181818, 145.454545], [145.454545, 30.303030]])
    adsb = np.array([[138.181818, 21.818182], [21.818182, 4.848485]])
    per_axis = radar + adsb
    S = np.zeros((4, 4))
    for axis in range(2):  # position-first order [x, y, vx, vy]
        S[np.ix_([axis, axis + 2], [axis, axis + 2])] = per_axis
    by_difference = Threshold(p_incorrect=0.01, state_difference=(100.0, 0.0, 0.0, 0.0))
    by_separation = Threshold(p_incorrect=0.01, min_separation_m=100.0)
    assert by_difference.design_noncentrality(S[None], 1)[0] == pytest.approx(34.438087, abs=1e-4)
    for rule in (by_difference, by_separation):
        assert rule.value(np.array([4]), covariance_sum=S[None])[0] == pytest.approx(14.881644, rel=1e-5)
    with pytest.raises(ValueError, match="exactly one"):
        Threshold(p_incorrect=0.01)
