"""The beam's turning rate in the plots' own times against the radars' scan periods."""

from __future__ import annotations

import pytest

from skytrack.io.time_units import BeamRateCheck
from skytrack.sim import load_scenario, simulate


@pytest.fixture(scope="module")
def two_radars():
    return simulate(load_scenario("two_radars"))


@pytest.mark.parametrize("scale, flagged", [(1.0, False), (1000.0, True), (0.5, False), (20.0, True)])
def test_times_in_another_unit_are_flagged_per_radar(two_radars, scale, flagged):
    """Seconds pass; milliseconds are named as such; a factor within 10 (a wrong scan period)
    passes; a factor of 20 is reported without a guess at the unit."""
    plots = two_radars.plots
    check = BeamRateCheck(two_radars.sensors)
    check.add(plots["sensor"].to_numpy(dtype=object), plots["time"].to_numpy() * scale, plots["azimuth_deg"].to_numpy())
    problems = check.problems()
    assert len(problems) == (2 if flagged else 0)
    if flagged:
        rate = 360.0 / two_radars.sensors["radar_east"].scan_period_s / scale
        east = next(p for p in problems if "radar_east" in p)
        assert f"turns {rate:.3g} deg/s" in east
        assert ("milliseconds" in east) == (scale == 1000.0)


def test_too_few_plots_say_nothing(two_radars):
    plots = two_radars.plots.iloc[:40]
    check = BeamRateCheck(two_radars.sensors)
    check.add(plots["sensor"].to_numpy(dtype=object), plots["time"].to_numpy() * 1000, plots["azimuth_deg"].to_numpy())
    assert check.problems() == []
    assert check.wants_more


def test_sample_is_bounded(two_radars):
    plots = two_radars.plots
    check = BeamRateCheck(two_radars.sensors)
    for _ in range(3):
        check.add(plots["sensor"].to_numpy(dtype=object), plots["time"].to_numpy(), plots["azimuth_deg"].to_numpy())
    assert not check.wants_more
    assert check.sampled == {"radar_west": 2000, "radar_east": 2000}
