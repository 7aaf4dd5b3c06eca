"""Multi-target tracker: schedule, scan processing, track bank, life cycle and output."""

from skytrack.core.tracks import TRACK_OUTPUT_COLUMNS
from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.tracker import Tracker

__all__ = ["TRACK_OUTPUT_COLUMNS", "Tracker", "TrackerConfig"]
