"""``skytrack identify``: identification of state estimates from two observation systems (spec 001).

Sub-commands (spec 001 R11-R13):

* ``potential`` / ``threshold`` — potential characteristics and Neyman–Pearson design
  (:mod:`skytrack.cli.identify_potential`, R11);
* ``pair`` — the sequential pair test on a reports file, report by report (R12);
* ``tracks`` — many-to-many identification of two sets of tracks (R13).

Only typer and rich are imported at module level; each command imports the library when it runs.
"""

from __future__ import annotations

import typer

from skytrack.cli.identify_pair import register_pair_command
from skytrack.cli.identify_potential import register_potential_commands
from skytrack.cli.identify_tracks import register_tracks_command

identify_app = typer.Typer(
    help="Identify state estimates of two observation systems (radar, ADS-B, IFF): spec 001.",
    no_args_is_help=True,
)
register_potential_commands(identify_app)  # R11: potential, threshold
register_pair_command(identify_app)  # R12: pair
register_tracks_command(identify_app)  # R13: tracks
