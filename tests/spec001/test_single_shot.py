"""Spec 001 R7 and R8: the single-shot test (25) on TV-2 (tolerance 1e-9 relative)."""

import numpy as np
import pytest

from skytrack.identify.model import cv_model
from skytrack.identify.sequential import SAME, SequentialPairTest
from skytrack.identify.single_shot import single_shot
from skytrack.identify.threshold import Threshold

ETA, R_ETA = np.array([12000.0, 8000.0]), np.array([[22500.0, 7500.0], [7500.0, 10000.0]])
XI, R_XI = np.array([12150.0, 7890.0]), np.diag([900.0, 900.0])


def test_tv2_statistic_fused_estimate_and_decision():
    result = single_shot(ETA, R_ETA, XI, R_XI)
    assert result.statistic[0] == pytest.approx(3.9026708918, rel=1e-9)
    assert -2.0 * result.loglik_same[0] == pytest.approx(3.9026708918, rel=1e-9)
    assert result.loglik_different[0] == 0.0
    assert result.loglik_different[0] - result.loglik_same[0] == pytest.approx(result.statistic[0] / 2, rel=1e-12)
    for fused in (result.fused_from_eta[0], result.fused_from_xi[0]):
        np.testing.assert_allclose(fused, [12138.8637392485, 7906.7451335446], rtol=1e-9)
    np.testing.assert_allclose(result.fused_covariance[0],
                               [[855.5907650521, 30.5568130376], [30.5568130376, 804.6627433228]], rtol=1e-9)
    assert result.p_value[0] == pytest.approx(0.1420841991, rel=1e-9)
    assert result.threshold[0] == pytest.approx(9.2103403720, rel=1e-9)
    assert result.decision[0] == SAME


def test_tv2_dropping_the_correlation_changes_l():
    """(27) with diagonal weights is not (25) for a correlated R_eta: 2.0716302047."""
    d = XI - ETA
    weights = np.diag(R_ETA) + np.diag(R_XI)
    assert np.sum(d ** 2 / weights) == pytest.approx(2.0716302047, rel=1e-9)
    assert single_shot(ETA, np.diag(np.diag(R_ETA)), XI, R_XI).statistic[0] == pytest.approx(2.0716302047, rel=1e-9)


def test_half_statistic_is_the_papers_literal_threshold():
    literal = single_shot(ETA, R_ETA, XI, R_XI, threshold=Threshold(p_correct=0.99), half_statistic=True)
    assert literal.statistic[0] == pytest.approx(3.9026708918 / 2, rel=1e-9)
    assert literal.threshold[0] == pytest.approx(9.2103403720 / 2, rel=1e-9)


def test_r8_sequential_test_with_one_report_each_is_the_single_shot():
    """H = I, one report from each system, diffuse: Lambda = l, joint state = (24), covariance C^-1."""
    model = cv_model(1, 0.0)  # state [x, v]: H = I measures both
    test = SequentialPairTest(model)
    test.add(1, 0.0, ETA, R_ETA, H=np.eye(2))
    test.add(2, 0.0, XI, R_XI, H=np.eye(2))
    result = single_shot(ETA, R_ETA, XI, R_XI)
    assert test.statistic[0] == pytest.approx(result.statistic[0], rel=1e-9)
    np.testing.assert_allclose(test.joint.x[0], result.fused_from_eta[0], rtol=1e-9)
    np.testing.assert_allclose(test.joint.P[0], result.fused_covariance[0], rtol=1e-9)


def test_r8_different_report_times():
    """Q = 0, reports at t_mu = 0 and t_nu = 2: Lambda = (xi - F eta)^T (F R_eta F^T + R_xi)^-1 (xi - F eta)."""
    model = cv_model(1, 0.0)
    test = SequentialPairTest(model)
    test.add(1, 0.0, ETA, R_ETA, H=np.eye(2))
    test.add(2, 2.0, XI, R_XI, H=np.eye(2))
    F = model.F(np.array([2.0]))[0]
    d = XI - F @ ETA
    expected = d @ np.linalg.solve(F @ R_ETA @ F.T + R_XI, d)
    assert test.statistic[0] == pytest.approx(expected, rel=1e-9)


def test_bad_covariance_is_reported():
    with pytest.raises(ValueError, match="R_xi"):
        single_shot(ETA, R_ETA, XI, np.zeros((2, 2)))
