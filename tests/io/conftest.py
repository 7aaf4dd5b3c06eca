"""Fixtures of the skytrack.io tests (builders live in io_samples.py)."""

from io_samples import sensor_set  # noqa: F401  (re-exported as a fixture)
