"""CI-sized run of the input fuzz suite (issue 6, item 8): malformed plots and sensors files.

The generator and outcome classifier live in ``benchmarks/fuzz_inputs.py`` (the full-size
run); here 5 200 cases over the four families, in chunks that ``pytest -n`` spreads over
workers, must end as located errors, counted skips or correct runs: no crash, no hang, no
silent data loss.  A failure message lists each failing case's replay record (family, seed,
index, mutation, exception); ``python benchmarks/fuzz_inputs.py --replay FILE`` re-runs them.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from fuzz_inputs import FAILURES, run_cases  # noqa: E402
from fuzz_mutations import FAMILIES  # noqa: E402

SEED = 20261124
CASES_PER_FAMILY = 1300
CHUNK = 100

# pyarrow's CSV reader cannot decode a malformed line holding invalid UTF-8 for the
# invalid-row handler; it reports that as "exception ignored" and then fails the read with
# a parse error, which the reader turns into a located InputError: the report is noise here
pytestmark = pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")


@pytest.mark.parametrize("start", range(0, CASES_PER_FAMILY, CHUNK))
@pytest.mark.parametrize("family", FAMILIES)
def test_malformed_inputs_end_in_located_errors_skips_or_tracks(family, start):
    results = run_cases(family, SEED, range(start, start + CHUNK))
    failures = [result.failure_record() for result in results if result.outcome in FAILURES]
    assert not failures, f"{len(failures)} failing cases:\n" + "\n".join(json.dumps(f) for f in failures)
