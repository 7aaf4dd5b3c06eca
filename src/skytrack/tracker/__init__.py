"""Multi-target tracker: track life cycle, scan processing, multi-sensor input."""

from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.tracker import TRACK_OUTPUT_COLUMNS, Tracker

__all__ = ["TRACK_OUTPUT_COLUMNS", "Tracker", "TrackerConfig"]
