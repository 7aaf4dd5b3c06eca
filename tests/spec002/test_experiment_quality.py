"""Spec 002 R16 (§3.6, gap G9): the poorly-planned-experiment diagnostic, TV12 (a) static and (b) remedies.

TV12(b) runs the deterministic linear Kalman covariance recursion (fixed V_w, R3 dynamics from
``ca_accel``; the set-up is study E6's ``remedy_run``) for 100 steps; diag P(100|100) is asserted at
the spec's 1e-6 relative, the literal ratio at its printed digits, the run verdict in both modes, the flagged fraction after burn-in and R5 on S.
"""

import numpy as np
import pytest

from skytrack.analysis.experiment_quality import (
    advice_text,
    check_experiment,
    covariance_recursion,
    culprits_of,
)
from skytrack.analysis.identifiability import check_identifiability
from skytrack.studies.adaptive_numerics import poor_experiment

COMPONENTS = ("x", "y", "vx", "vy", "ax", "ay", "b_x")
UNITS = ("m", "m", "m/s", "m/s", "m/s^2", "m/s^2", "m")

# ---------------------------------------------------------------- TV12 (a) static

STATIC_P = np.diag([400.0, 400.0, 4.0, 4.0, 1e-4, 1e-4, 9e4])
STATIC_V = np.diag([400.0, 400.0, 0.25])
STATIC_CHANNEL_UNITS = ("m", "m", "m/s")


def static(mode, **options):
    return check_experiment(STATIC_P, STATIC_V, components=COMPONENTS, state_units=UNITS,
                            measurement_units=STATIC_CHANNEL_UNITS, mode=mode, **options)


def test_tv12a_literal_ratio_225_is_flagged():
    quality = static("literal")
    assert quality.literal_ratio[0] == pytest.approx(225.0, rel=1e-12)
    assert quality.flagged_steps.tolist() == [True]
    assert quality.culprit_components == ("b_x",)  # only P_bx ≥ 100 · max V_η
    assert quality.verdict == "poorly planned experiment"  # one step ≤ burn-in: the last step decides


def test_tv12a_matched_ratios_and_no_reference():
    quality = static("matched")
    ratio = quality.component_ratio[0]
    np.testing.assert_allclose(ratio[[0, 1, 6]], [1.0, 1.0, 225.0], rtol=1e-12)
    np.testing.assert_allclose(ratio[[2, 3]], [16.0, 16.0], rtol=1e-12)
    assert np.isnan(ratio[[4, 5]]).all()
    assert quality.no_reference() == ("ax", "ay")
    assert quality.flagged_components[0].tolist() == [False] * 6 + [True]
    assert quality.poorly_planned and quality.culprit_components == ("b_x",)


def test_user_reference_overrides_the_channel_variance():
    quality = static("matched", reference={"b_x": 1e4, "ax": 1e-7})
    assert quality.component_ratio[0, 6] == pytest.approx(9.0)
    assert quality.component_ratio[0, 4] == pytest.approx(1000.0)
    assert quality.culprit_components == ("ax",)


def test_threshold_orders():
    assert static("matched", orders=2.5).verdict == "ok"  # 225 < 10^2.5
    assert static("matched", orders=1).culprit_components == ("vx", "vy", "b_x")


def test_fixed_advice_wording_with_culprits_channels_and_priors():
    text = advice_text(["x", "b_x"], 2, culprits=["ax", "b_x"], channels=["x_radar"])
    assert text == (
        "Estimate-error variances of x, b_x exceed the measurement-error variances by more than 10^2: "
        "the experiment is poorly planned. Revise first the mathematical models in use, then "
        "(1) reduce the dimension of the parameter vector of the state model "
        "(not identifiable from the measurements: ax, b_x); "
        "(2) bring in additional measurement data (channels acting on them: x_radar); "
        "(3) use the available prior information (tighter priors on x, b_x)."
    )
    assert "(1) reduce the dimension of the parameter vector of the state model; (2)" in advice_text(["x"])


def test_burn_in_and_fraction_decide_the_run():
    # 40 steps: flagged on steps 1-25 and on 31-35; after the burn-in of 20: 10 of 20 flagged
    K = 40
    P = np.broadcast_to(np.diag([1.0, 1.0]), (K, 2, 2)).copy()
    flagged = np.zeros(K, bool)
    flagged[:25] = flagged[30:35] = True
    P[flagged, 0, 0] = 1e3
    common = dict(components=("x", "y"), state_units=("m", "m"), measurement_units=("m",))
    quality = check_experiment(P, np.eye(1), **common)
    assert quality.considered.sum() == 20 and quality.flagged_fraction == pytest.approx(0.5)
    assert quality.poorly_planned  # ≥ f = 0.5
    assert not check_experiment(P, np.eye(1), fraction=0.6, **common).poorly_planned
    assert check_experiment(P, np.eye(1), burn_in=30, **common).flagged_fraction == pytest.approx(0.5)
    assert not check_experiment(P, np.eye(1), burn_in=35, **common).poorly_planned
    # a run no longer than the burn-in is decided by its last step
    assert check_experiment(P[:20], np.eye(1), **common).poorly_planned
    assert not check_experiment(P[25:30], np.eye(1), **common).poorly_planned


# ---------------------------------------------------------------- TV12 (b) remedies

TV12B = {
    # variant: (diag P(100|100) as printed, literal ratio, poorly planned, R5 verdict, D)
    "V0": ("500153.793 115.859244 5.371313 5.371296 0.107246 0.107246 500037.912", 1250.38, True,
           "not_identifiable", ["ax", "b_x"]),
    "V1": ("115.859244 115.859244 5.371296 5.371296 0.107246 0.107246", 0.2896, False, "identifiable", []),
    "V2": ("29.047469 28.847335 2.324850 2.324849 0.079815 0.079815 5.003257", 0.0726, False,
           "identifiable", []),
    "V3": ("215.859389 115.859244 5.371313 5.371296 0.107246 0.107246 100.000003", 0.5396, False,
           "not_identifiable", ["ax", "b_x"]),
}


def remedy_run(variant):
    """(model, H, V_η, channel names, P(k|k) for k = 1 … 100) of one TV12(b) variant, set up by study E6."""
    run = poor_experiment.remedy_run(variant)
    return run.model, run.H, run.noise_cov, list(run.channels), run.P


@pytest.mark.parametrize("variant", sorted(TV12B))
def test_tv12b_remedies_table(variant):
    diag, literal, poorly, r5_verdict, indistinguishable = TV12B[variant]
    model, H, V_eta, channels, P = remedy_run(variant)
    assert P.shape == (100, model.dim, model.dim)
    # 1e-6 relative, or half a unit of the last printed decimal (0.107246 stands for 0.10724581)
    assert poor_experiment.printed_match(np.diag(P[-1]), diag, rtol=1e-6), (np.diag(P[-1]), diag)
    checks = check_identifiability(H=H, F=model.F(np.zeros(model.dim), 1.0), h_a=model.h_a,
                                   noise_cov=V_eta, names=model.parameters)
    assert checks.verdicts == [r5_verdict]
    assert checks.indistinguishable_names(0) == indistinguishable
    units = ["m"] * len(channels)
    for mode in ("matched", "literal"):
        quality = check_experiment(P, V_eta, components=model.components, state_units=model.units,
                                   measurement_units=units, mode=mode, culprits=culprits_of(checks),
                                   observation=H, channels=channels)
        assert quality.literal_ratio[-1] == pytest.approx(literal, abs=0.006 if literal > 1 else 6e-5)
        assert quality.poorly_planned is poorly
        assert quality.flagged_fraction == (1.0 if poorly else 0.0)
        if poorly:
            assert quality.culprit_components == ("x", "b_x")
            assert quality.advice == advice_text(["x", "b_x"], 2, culprits=["ax", "b_x"], channels=["x_radar"])
        else:
            assert quality.verdict == "ok" and quality.advice is None


def test_covariance_recursion_matches_the_information_form():
    # one step of the recursion against P⁺ = (V_x⁻¹ + Hᵀ V_η⁻¹ H)⁻¹
    model, H, V_eta, _, _ = remedy_run("V2")
    F = model.F(np.zeros(model.dim), 1.0)
    P0 = np.diag([100.0, 200.0, 10.0, 20.0, 1.0, 2.0, 50.0])
    (P1,) = covariance_recursion(F, model.V_w, model.h_a, H, V_eta, P0, 1)
    G = F @ model.h_a.T
    predicted = F @ P0 @ F.T + G @ model.V_w @ G.T
    expected = np.linalg.inv(np.linalg.inv(predicted) + H.T @ np.linalg.inv(V_eta) @ H)
    np.testing.assert_allclose(P1, expected, rtol=1e-9)
