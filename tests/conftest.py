"""Suite-wide test settings.

``SKYTRACK_WORKERS=1``: the study commands run their tasks in process unless a test asks for
``--workers N`` or ``--scheduler`` (issue 11 item 6); a pool per CLI call would cost seconds of
worker start-up each, under ``pytest -n 2`` on two cores.  tests/studies/test_parallel.py checks
the pools and Dask explicitly.
"""

import os

os.environ.setdefault("SKYTRACK_WORKERS", "1")
