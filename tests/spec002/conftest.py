"""Shared pieces of the spec 002 tests: the long-run simulation of TV11 (c)/(d).

The simulation itself is :func:`skytrack.studies.adaptive_numerics.vw_estimator.run_bank` (study E7
runs the same scene); the fixture hands it to the TV11 tests.
"""

import pytest

from skytrack.studies.adaptive_numerics.vw_estimator import run_bank


@pytest.fixture
def tv11_bank():
    """:func:`run_bank`: TV11's 1-D constant-acceleration scene run as a bank of seeds."""
    return run_bank
