"""``python -m skytrack`` runs the command line."""

from skytrack.cli.main import app

app()
