"""skytrack.io — schemas, readers and writers of the FORMATS.md files.

Tables (plots, adsb, truth, tracks) are Parquet (``.parquet``/``.pq``) or CSV
(``.csv``/``.csv.gz``), chosen by extension; ``sensors.json`` is JSON.  Every reader
validates with vectorised checks and raises :class:`InputError` naming the file, row
(and CSV line) and column of the first problem; with ``lenient=True`` it skips and counts
bad rows and returns ``(data, ReadReport)``.  Dtypes follow one policy, described in
:mod:`skytrack.io.schema` (float64, int64 / nullable Int64, pandas ``str`` text, bool;
absent optional columns stay absent).  :func:`read_state_vectors` reads recorded
aircraft state vectors (the traffic library's or the OpenSky database's layout, also
JSON lines) into SI units for the simulator.  Writers validate the same way, put the known
columns in FORMATS.md order followed by the extras, and create parent directories.
"""

from skytrack.io.adsb import read_adsb, write_adsb
from skytrack.io.errors import InputError, InputWarning, ReadReport, SkippedRows, refuse_overwriting
from skytrack.io.identity_events import identity_events_path, read_identity_events, write_identity_events
from skytrack.io.plots import iter_plot_batches, iter_plots, read_plots, write_plots
from skytrack.io.schema import (
    ADSB_COLUMNS,
    ADSB_SCHEMA,
    IDENTITY_EVENT_SCHEMA,
    IFF_VALUES,
    OPENSKY_COLUMNS,
    PLOT_COLUMNS,
    PLOT_REQUIRED,
    PLOT_SCHEMA,
    STRING_DTYPE,
    TEXT_COLUMNS,
    TRACK_COLUMNS,
    TRACK_SCHEMA,
    TRACK_STATUS_VALUES,
    TRUTH_COLUMNS,
    TRUTH_SCHEMA,
    Column,
    TableSchema,
)
from skytrack.io.sensors import read_sensors, sensor_set_from_dict, write_sensors
from skytrack.io.state_vectors import STATE_COLUMNS, read_state_vectors
from skytrack.io.tables import read_table, table_format, write_table
from skytrack.io.tracks import read_tracks, write_tracks
from skytrack.io.truth import DEFAULT_MAX_GAP_S, read_truth, write_truth

__all__ = [
    "iter_plot_batches",
    "iter_plots",
    "read_plots",
    "write_plots",
    "read_sensors",
    "write_sensors",
    "sensor_set_from_dict",
    "read_truth",
    "write_truth",
    "read_state_vectors",
    "STATE_COLUMNS",
    "read_tracks",
    "write_tracks",
    "read_identity_events",
    "write_identity_events",
    "identity_events_path",
    "IDENTITY_EVENT_SCHEMA",
    "read_adsb",
    "write_adsb",
    "read_table",
    "write_table",
    "table_format",
    "InputError",
    "InputWarning",
    "refuse_overwriting",
    "ReadReport",
    "SkippedRows",
    "Column",
    "TableSchema",
    "PLOT_SCHEMA",
    "PLOT_COLUMNS",
    "PLOT_REQUIRED",
    "ADSB_SCHEMA",
    "ADSB_COLUMNS",
    "TRUTH_SCHEMA",
    "TRUTH_COLUMNS",
    "TRACK_SCHEMA",
    "TRACK_COLUMNS",
    "OPENSKY_COLUMNS",
    "TEXT_COLUMNS",
    "IFF_VALUES",
    "TRACK_STATUS_VALUES",
    "STRING_DTYPE",
    "DEFAULT_MAX_GAP_S",
]
