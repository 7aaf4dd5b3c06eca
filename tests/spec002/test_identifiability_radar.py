"""Spec 002 TV8 (R4, R5, R10): the whole radar identifiability table through ``check_along``.

Every row of TV8 (parameters ω / ω+b_ṙ / a_x,a_y / +b_x / +b_ṙ; radial and tangential flight; the
measurement sets pos, ṙ, pos+ṙ): verdict, Z, D, ``m < p`` exactly, κ at the spec's 1 % relative.
Also the unwhitened {a_x, a_y, b_ṙ} radial pos+ṙ margin (0.2361, identifiable) and the polar (r, az)
equivalence for every set without b_x (same verdict, Z, D; κ within 4 %).  A bias whose channel is
not measured is appended to the model with no measurement row acting on it (an exactly zero column).
The spec's TV8 table and the cell builder are study E2's (:mod:`skytrack.studies.identifiability.radar_cells`),
so that the code base holds one copy of them.
"""

import numpy as np
import pytest

from skytrack.analysis.identifiability_along import check_along, check_along_tracks, linearise_along
from skytrack.models.augmented import ca_accel, ct_omega
from skytrack.models.augmented_measurements import measurement_for, one_step_sensitivity
from skytrack.studies.identifiability import radar_cells
from skytrack.studies.identifiability.radar_cells import (
    I,
    MEASUREMENT_SETS,
    N,
    PARAMETER_SETS,
    TV8_P0,
    TV8_SIGMA,
    TV8_TABLE,
    TV8_VELOCITY,
)

TABLE = TV8_TABLE
VELOCITY = TV8_VELOCITY


def radar_case(parameters, geometry, measurement_set):
    """(model, measurement, states x(k-1), φ(x(k-1)), V_η) of one TV8 cell."""
    kind, biases = PARAMETER_SETS[parameters]
    model, measurement = radar_cells.radar_case(kind, biases, MEASUREMENT_SETS[measurement_set])
    start = np.zeros(model.dim)
    start[:4] = (*TV8_P0, *TV8_VELOCITY[geometry])
    states = np.stack([start, model.phi(start, 1.0)])
    return model, measurement, states, radar_cells.noise_covariance(measurement, TV8_SIGMA)


def run(parameters, geometry, measurement_set, whiten=True):
    model, measurement, states, noise_cov = radar_case(parameters, geometry, measurement_set)
    return check_along(model, measurement, states, 1.0, noise_cov=noise_cov if whiten else None)


def cell_mismatches(record, verdict, kappa, zero, indistinguishable, fewer, kappa_rtol) -> list[str]:
    """What differs between one checked TV8 cell and the spec's table (empty when it matches)."""
    checks = record.checks
    found = {
        "steps": len(checks), "verdict": checks.verdicts, "global": record.global_verdict,
        "Z": tuple(checks.zero_influence_names(0)), "D": tuple(checks.indistinguishable_names(0)),
        "m<p": bool(checks.fewer_channels[0]),
    }
    wanted = {"steps": 1, "verdict": [verdict], "global": verdict, "Z": zero, "D": indistinguishable, "m<p": fewer}
    problems = [f"{key}: {found[key]!r} != {wanted[key]!r}" for key in wanted if found[key] != wanted[key]]
    k = float(checks.kappa[0])
    if kappa == 0.0 and k != 0.0:
        problems.append(f"kappa {k} != 0")
    elif kappa not in (None, 0.0) and abs(k - kappa) > kappa_rtol * kappa:
        problems.append(f"kappa {k} not within {kappa_rtol:.0%} of {kappa}")
    if verdict == N and k > 1e-6:
        problems.append(f"kappa {k} > 1e-6 for a not_identifiable cell")
    return problems


@pytest.mark.parametrize("cell", sorted(TABLE), ids=lambda c: "-".join(c))
def test_tv8_table_cell(cell):
    assert cell_mismatches(run(*cell), *TABLE[cell], kappa_rtol=0.01) == []


def test_tv8_table_is_complete():
    assert len(TABLE) == len(PARAMETER_SETS) * 2 * 3 == 30


def test_tv8_unwhitened_accelerations_and_doppler_bias_radial_hide_the_weakness():
    record = run("ax,ay,b_rdot", "radial", "pos+rdot", whiten=False)
    assert record.verdicts == [I]
    assert record.checks.kappa[0] == pytest.approx(0.2361, abs=5e-5)
    assert record.checks.indistinguishable_names(0) == []


POLAR_CELLS = [(params, geometry, measurement_set)
               for params in PARAMETER_SETS if "b_x" not in params
               for geometry in VELOCITY for measurement_set in ("pos", "pos+rdot")]


@pytest.mark.parametrize("cell", POLAR_CELLS, ids=lambda c: "-".join(c))
def test_tv8_polar_gives_the_same_decision(cell):
    params, geometry, measurement_set = cell
    verdict, kappa, zero, indistinguishable, fewer = TABLE[cell]
    record = run(params, geometry, measurement_set.replace("pos", "polar"))
    assert cell_mismatches(record, verdict, kappa, zero, indistinguishable, fewer, kappa_rtol=0.04) == []


def test_check_along_linearises_at_the_previous_state_and_its_prediction():
    # F_k at x_{k-1} and H_k at φ(x_{k-1}) along a curved path, all steps in one call
    model = ct_omega()
    measurement = measurement_for(model, ("pos", "rdot"))
    states = [np.array([30_000.0, 0.0, 0.0, 200.0, 0.02])]
    for _ in range(5):
        states.append(model.phi(states[-1], 2.0))
    states = np.stack(states)
    H, F = linearise_along(model, measurement, states, 2.0)
    assert H.shape == (5, 3, 5) and F.shape == (5, 5, 5)
    np.testing.assert_array_equal(F, model.F(states[:-1], 2.0))
    np.testing.assert_array_equal(H, measurement.H(model.phi(states[:-1], 2.0)))
    record = check_along(model, measurement, states, 2.0, noise_cov=np.diag([2500.0, 2500.0, 1.0]))
    np.testing.assert_allclose(record.checks.sensitivity,
                               one_step_sensitivity(model, measurement, states[:-1], 2.0), rtol=1e-14)
    assert list(record.steps) == [1, 2, 3, 4, 5]
    assert record.checks.names == ("omega",)


def test_check_along_window_and_full_state_pass_through():
    model = ca_accel()
    measurement = measurement_for(model, "pos")
    start = np.array([30_000.0, 0.0, 0.0, 200.0, 0.0, 0.0])
    states = np.stack([start] + [model.phi(start, float(k)) for k in range(1, 6)])
    record = check_along(model, measurement, states, 1.0, noise_cov=np.diag([400.0, 400.0]),
                         window=3, unknown="all")
    assert len(record.checks) == 3
    assert record.checks.names == model.components
    assert record.global_verdict == I


def test_check_along_rejects_a_measurement_of_other_states():
    model = ca_accel()
    measurement = measurement_for(model, "pos").with_bias("x")
    with pytest.raises(ValueError, match="augment_for_biases"):
        check_along(model, measurement, np.zeros((2, 6)), 1.0)


@pytest.mark.parametrize("window, unknown", [(1, "parameters"), (2, "parameters"), (3, "all")])
def test_check_along_tracks_equals_check_along_per_track(window, unknown):
    # radial, tangential and a turning track in one batched call; each record as for the track alone
    model = ct_omega()
    measurement = measurement_for(model, ("pos", "rdot"))
    starts = np.array([[30_000.0, 0.0, -200.0, 0.0, 0.0], [30_000.0, 0.0, 0.0, 200.0, 0.0],
                       [20_000.0, 5_000.0, 150.0, -100.0, 0.03]])
    tracks = [starts]
    for _ in range(5):
        tracks.append(model.phi(tracks[-1], 1.0))
    states = np.stack(tracks, axis=1)  # (B, N, n)
    cov = np.diag([2500.0, 2500.0, 1.0])
    records = check_along_tracks(model, measurement, states, 1.0, noise_cov=cov, window=window, unknown=unknown)
    assert len(records) == 3
    for track, record in zip(states, records):
        alone = check_along(model, measurement, track, 1.0, noise_cov=cov, window=window, unknown=unknown)
        assert record.verdicts == alone.verdicts
        assert list(record.steps) == list(alone.steps)
        assert record.checks.names == alone.checks.names
        np.testing.assert_allclose(record.checks.kappa, alone.checks.kappa, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(record.checks.sensitivity, alone.checks.sensitivity, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(record.checks.zero_influence, alone.checks.zero_influence)
        np.testing.assert_array_equal(record.checks.indistinguishable, alone.checks.indistinguishable)
    if window == 1:
        # the radial track's Doppler-free step structure differs from the tangential one's
        assert records[0].checks.sensitivity[0, 2, 0] == 0.0
        assert records[1].checks.sensitivity[0, 2, 0] == pytest.approx(-199.99111155553362, rel=1e-12)
