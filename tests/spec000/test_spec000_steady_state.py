"""Spec 000 R12 and TV8: steady state at P_D = 1 from the DARE, against 20 000 filter iterations."""

import math

import numpy as np
import pytest

from skytrack.filters import covariance_recursion, steady_state
from skytrack.models import SingerAxisModel

SIGMAS = (30.0, 100.0, 200.0, 300.0, 500.0, 1000.0, 3000.0)
# sigma -> {(variant, discretization): (FS11, FES11)}
TV8 = {
    30.0: {("pos", "paper"): (0.94970466, 3.03277549), ("posvel", "paper"): (0.82731639, 2.26977543),
           ("pos", "exact"): (0.95002593, 3.04328702), ("posvel", "exact"): (0.82964931, 2.23010085)},
    100.0: {("pos", "paper"): (0.88257939, 1.87717591), ("posvel", "paper"): (0.59406149, 0.96039294),
            ("pos", "exact"): (0.88263081, 1.87767077), ("posvel", "exact"): (0.59621532, 0.94249716)},
    200.0: {("pos", "paper"): (0.83029221, 1.48977216), ("posvel", "paper"): (0.45522883, 0.60070467),
            ("pos", "exact"): (0.83026110, 1.48959251), ("posvel", "exact"): (0.45667138, 0.59215978)},
    300.0: {("pos", "paper"): (0.79602296, 1.31516126), ("posvel", "paper"): (0.38287111, 0.46518538),
            ("pos", "exact"): (0.79596185, 1.31488574), ("posvel", "exact"): (0.38389635, 0.46001865)},
    500.0: {("pos", "paper"): (0.74988467, 1.13349500), ("posvel", "paper"): (0.30403767, 0.34346176),
            ("pos", "exact"): (0.74979898, 1.13319912), ("posvel", "exact"): (0.30465921, 0.34087079)},
    1000.0: {("pos", "paper"): (0.68367987, 0.93682746), ("posvel", "paper"): (0.21918840, 0.23343023),
             ("pos", "exact"): (0.68357644, 0.93656141), ("posvel", "exact"): (0.21948838, 0.23249278)},
    3000.0: {("pos", "paper"): (0.57564429, 0.70397962), ("posvel", "paper"): (0.12823498, 0.13101340),
             ("pos", "exact"): (0.57553334, 0.70377672), ("posvel", "exact"): (0.12833679, 0.13086274)},
}


@pytest.mark.parametrize("variant", ["pos", "posvel"])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_tv8_steady_state_table(variant, disc):
    model = SingerAxisModel(60.0, 1.0, disc)
    for sigma in SIGMAS:
        P_pred, P_filt = steady_state(model, variant, sigma=sigma, dt=10.0, sigma_v=5.0)
        fs11, fes11 = TV8[sigma][(variant, disc)]
        assert math.sqrt(P_filt[0, 0]) / sigma == pytest.approx(fs11, abs=1e-7)
        assert math.sqrt(P_pred[0, 0]) / sigma == pytest.approx(fes11, abs=1e-7)


def test_tv8_full_diagonals_paper_sigma_100():
    model = SingerAxisModel(60.0, 1.0, "paper")
    P_pred, P_filt = steady_state(model, "pos", sigma=100.0, dt=10.0)
    np.testing.assert_allclose(np.diag(P_filt), [7789.46385, 88.7311817, 0.570094542], rtol=1e-8)
    assert P_pred[0, 0] == pytest.approx(35237.8939, rel=1e-8)
    P_pred, P_filt = steady_state(model, "posvel", sigma=100.0, dt=10.0, sigma_v=5.0)
    np.testing.assert_allclose(np.diag(P_filt), [3529.09051, 17.3961928, 0.392725662], rtol=1e-8)
    assert P_pred[0, 0] == pytest.approx(9223.54607, rel=1e-8)


@pytest.mark.parametrize("variant", ["pos", "posvel"])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r12_dare_agrees_with_20000_filter_iterations(variant, disc):
    """R12: the DARE solution against 20 000 P_D = 1 iterations of the production recursion (1e-8)."""
    model = SingerAxisModel(60.0, 1.0, disc)
    sig = np.array(SIGMAS)
    P0 = np.stack([np.diag([s * s, 25.0, 1.0]) for s in sig])  # the paper's start (A0)
    run = covariance_recursion(model, variant, sigma=sig, sigma_v=5.0, dt=10.0, P0=P0,
                               detection=np.ones((20000, sig.size), bool), n_scans=20000)
    for k, s in enumerate(sig):
        ss = steady_state(model, variant, sigma=s, dt=10.0, sigma_v=5.0)
        iterated = run.final[k]
        assert np.max(np.abs(ss.P_filt - iterated)) <= 1e-8 * np.max(np.abs(iterated)), s
        # and P- is the prediction of P+ (Theorem 2)
        F, Q = model.F(10.0), model.Q(10.0)
        np.testing.assert_allclose(ss.P_pred, F @ ss.P_filt @ F.T + Q, rtol=1e-12, atol=1e-12 * np.abs(ss.P_pred).max())


def test_r12_riccati_residual_and_positive_definiteness():
    model = SingerAxisModel(60.0, 1.0, "exact")
    F, Q = model.F(10.0), model.Q(10.0)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    R = np.diag([200.0**2, 5.0**2])
    P, _ = steady_state(model, "posvel", sigma=200.0, dt=10.0, sigma_v=5.0)
    S = H @ P @ H.T + R
    residual = F @ (P - P @ H.T @ np.linalg.solve(S, H @ P)) @ F.T + Q - P
    assert np.max(np.abs(residual)) <= 1e-12 * np.max(np.abs(P))
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_steady_state_validation():
    model = SingerAxisModel(60.0, 1.0, "paper")
    with pytest.raises(ValueError):
        steady_state(model, "pos", sigma=0.0, dt=10.0)
    with pytest.raises(ValueError):
        steady_state(model, "pos", sigma=100.0, dt=-1.0)
    with pytest.raises(ValueError):
        steady_state(model, "posvel", sigma=100.0, dt=10.0)
    with pytest.raises(ValueError):
        steady_state(model, "vel", sigma=100.0, dt=10.0)
