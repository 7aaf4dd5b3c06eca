"""The defaults `skytrack track --help` shows are TrackerConfig's (no drift).

The CLI cannot import TrackerConfig at start-up (numpy, scipy behind it), so
``skytrack.cli.defaults`` writes them out; this test ties both to the dataclass.
"""

from __future__ import annotations

import typer.main

from skytrack.app.run import DEFAULT_CHUNK_ROWS
from skytrack.cli import defaults
from skytrack.cli.main import app
from skytrack.tracker import TrackerConfig

#: option (parameter name of the `track` command) -> TrackerConfig field
OPTION_FIELDS = {
    "model": "model",
    "q": "cv_q",
    "tau": "singer_tau_s",
    "sigma_a": "singer_sigma_a",
    "discretization": "discretization",
    "manoeuvre_scale": "manoeuvre_q_scale",
    "p_gate": "p_gate",
    "gate_threshold": "gate_threshold",
    "delete_misses": "delete_misses",
    "init": "init",
    "tracking_dim": "tracking_dim",
    "default_altitude": "default_altitude_m",
    "output_interval": "output_interval_s",
    "full_covariance": "full_covariance",
    "track_logic": "track_logic",
    "false_tracks_per_hour": "false_tracks_per_hour",
    "report_max_misses": "report_max_misses",
}


def _field_defaults() -> dict:
    return TrackerConfig().to_dict(flat=True)


def _track_option_defaults() -> dict:
    command = typer.main.get_command(app).commands["track"]
    return {param.name: param.default for param in command.params}


def test_every_track_option_default_is_the_tracker_config_default():
    fields = _field_defaults()
    options = _track_option_defaults()
    for option, field in OPTION_FIELDS.items():
        assert options[option] == fields[field], f"--{option.replace('_', '-')} vs TrackerConfig.{field}"
    assert options["confirm"] == f"{fields['confirm_m']}/{fields['confirm_n']}"
    assert options["chunk_rows"] == DEFAULT_CHUNK_ROWS


def test_the_defaults_module_matches_tracker_config():
    fields = _field_defaults()
    written = {name: value for name, value in vars(defaults).items() if name.isupper() and name != "CHUNK_ROWS"}
    by_field = {name.lower(): value for name, value in written.items()}
    assert by_field, "skytrack.cli.defaults lists no defaults"
    for field, value in by_field.items():
        assert field in fields, f"skytrack.cli.defaults.{field.upper()} names no TrackerConfig field"
        assert value == fields[field] and type(value) is type(fields[field]), field
    assert defaults.CHUNK_ROWS == DEFAULT_CHUNK_ROWS
