"""Checkpoints of a live tracker: the whole tracking state in one ``.npz`` file, written atomically,
and a tracker (and ADS-B labeller) rebuilt from it after a restart (issue 11 item 3: "checkpoints
the track bank ... at least every 10 s and, after a restart, resumes every track confirmed at the
last checkpoint").

:func:`save_checkpoint` writes the arrays of :meth:`skytrack.tracker.Tracker.checkpoint` (every
filter state, bank column, clutter map, learned code counts, the open windows' plots, the output
clock...: :mod:`skytrack.tracker.state`) and, when given, the state of the
:class:`~skytrack.app.identification.TrackLabeler` (its identification pairs and their sequential
test sums; :mod:`skytrack.app.labeler_state`, no pickle: the file is read with
``allow_pickle=False``), plus a JSON header: the format version, the tracker configuration, the sensors'
names and a SHA-256 of the sensors description (epoch, origin and sensors of sensors.json), the
save time and the number of tracks.  The file is written to a temporary file in the same
directory, flushed to disk (fsync) and renamed over the old checkpoint (``os.replace``), so a
``kill -9`` or a power cut at any moment leaves either the previous checkpoint or the new one,
never a half-written file.

:func:`load_checkpoint` refuses, with a :class:`CheckpointError` naming the file and the
difference, a checkpoint saved for other sensors or another configuration, of another format
version, or damaged (truncated, not a zip archive, a CRC error, a missing array).  The service
then starts fresh and says so.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

import numpy as np

#: file format version, in the header; another version is refused
CHECKPOINT_VERSION = 1
CHECKPOINT_KIND = "skytrack-checkpoint"
HEADER_KEY = "header"


class CheckpointError(ValueError):
    """A checkpoint file that cannot be used: damaged, of another version, or saved for other
    sensors or another configuration (the message names the file)."""


def sensors_fingerprint(sensors) -> str:
    """SHA-256 of what the tracking state depends on in sensors.json: epoch, origin and sensors."""
    described = sensors.to_dict()
    relevant = {key: described.get(key) for key in ("epoch_utc", "origin", "sensors")}
    text = json.dumps(relevant, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _config_dict(config) -> dict:
    """The configuration as its JSON round trip (tuples become lists), for comparison."""
    return json.loads(json.dumps(config.to_dict(), default=str))


def _flatten(data, prefix: str = "") -> dict:
    if not isinstance(data, dict):
        return {prefix: data}
    out = {}
    for key, value in data.items():
        out.update(_flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    return out


def save_checkpoint(path, tracker, labeler=None, *, extra: dict | None = None) -> None:
    """Write ``tracker``'s state (and ``labeler``'s, when given) to ``path`` atomically (see the
    module docstring).  The track rows and identity events not yet drained are part of the state:
    drain them first when they were written elsewhere, or they are produced again after a restore.
    ``extra``: a JSON-able dict of the caller's own (a service's frame counter...), returned by
    :func:`read_checkpoint` as ``header["extra"]``."""
    from skytrack.tracker.bank import CONFIRMED

    path = Path(path)
    arrays, meta = tracker.checkpoint()
    payload = {f"tracker.{name}": value for name, value in arrays.items()}
    if labeler is not None:
        payload.update({f"labeler.{name}": value for name, value in labeler.state().items()})
    header = {
        "kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION, "saved_unix_s": time.time(),
        "sensor_names": list(tracker.sensors.names), "sensors_sha256": sensors_fingerprint(tracker.sensors),
        "config": _config_dict(tracker.config), "tracker": meta, "labeler": labeler is not None,
        "tracks": len(tracker.bank), "confirmed_tracks": int((tracker.bank.status == CONFIRMED).sum()),
        "last_plot_s": float(np.max(tracker.schedule.last_time)) if len(tracker.schedule.last_time) else None,
        "extra": dict(extra) if extra is not None else {},
    }
    payload[HEADER_KEY] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "wb") as handle:
            np.savez(handle, **payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    finally:
        if temporary.exists():
            temporary.unlink()
    # the rename itself is durable once the directory is synced
    directory = os.open(path.parent if str(path.parent) else ".", os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


def read_checkpoint(path) -> tuple[dict, dict[str, np.ndarray]]:
    """``(header, arrays)`` of a checkpoint file, every array read (so that a damaged member shows
    now); :class:`CheckpointError` when the file is damaged or not a checkpoint of this version."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no checkpoint file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except Exception as exc:  # zipfile, zlib, numpy format errors: all mean a damaged file
        raise CheckpointError(f"{path}: damaged checkpoint file ({path.stat().st_size} bytes; "
                              f"{type(exc).__name__}: {exc})") from None
    if HEADER_KEY not in arrays:
        raise CheckpointError(f"{path}: not a skytrack checkpoint (no header array)")
    try:
        header = json.loads(arrays.pop(HEADER_KEY).tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: damaged checkpoint header ({exc})") from None
    if not isinstance(header, dict) or header.get("kind") != CHECKPOINT_KIND:
        raise CheckpointError(f"{path}: not a skytrack checkpoint")
    if header.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint format version {header.get('version')!r}; this skytrack reads "
                              f"version {CHECKPOINT_VERSION}")
    return header, arrays


def load_checkpoint(path, sensors, config=None):
    """``(tracker, labeler or None)`` rebuilt from the checkpoint at ``path`` for ``sensors`` and
    ``config`` (None: the default configuration), which must be those it was saved with.

    Raises :class:`CheckpointError` (naming the file and what differs) for a damaged file, another
    format version, other sensors or another configuration; ``FileNotFoundError`` when there is
    no file."""
    from skytrack.app.identification import TrackLabeler
    from skytrack.tracker.config import TrackerConfig
    from skytrack.tracker.tracker import Tracker

    path = Path(path)
    config = config if config is not None else TrackerConfig()
    header, arrays = read_checkpoint(path)
    fingerprint = sensors_fingerprint(sensors)
    if header.get("sensors_sha256") != fingerprint:
        raise CheckpointError(
            f"{path}: checkpoint was saved for other sensors (sensors {header.get('sensor_names')}, sha256 "
            f"{str(header.get('sensors_sha256'))[:12]}...; this sensors.json: sensors {list(sensors.names)}, sha256 "
            f"{fingerprint[:12]}...): start with the sensors.json it was saved with, or without the checkpoint")
    saved, current = _flatten(header.get("config") or {}), _flatten(_config_dict(config))
    differing = sorted(key for key in set(saved) | set(current) if saved.get(key, "<absent>") !=
                       current.get(key, "<absent>"))
    if differing:
        shown = ", ".join(f"{key} {saved.get(key, '<absent>')!r} -> {current.get(key, '<absent>')!r}"
                          for key in differing[:5])
        more = f" and {len(differing) - 5} more" if len(differing) > 5 else ""
        raise CheckpointError(f"{path}: checkpoint was saved with another tracker configuration ({shown}{more})")
    tracker_arrays = {name[len("tracker."):]: value for name, value in arrays.items() if name.startswith("tracker.")}
    try:
        tracker = Tracker.restore(sensors, config, tracker_arrays, header["tracker"])
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise CheckpointError(f"{path}: damaged checkpoint: the tracker state does not fit "
                              f"({type(exc).__name__}: {exc})") from None
    labeler = None
    if header.get("labeler"):
        labeler_arrays = {name[len("labeler."):]: value for name, value in arrays.items()
                          if name.startswith("labeler.")}
        try:
            labeler = TrackLabeler.restore(labeler_arrays)
        except (KeyError, ValueError, TypeError, IndexError, UnicodeDecodeError) as exc:
            raise CheckpointError(f"{path}: damaged checkpoint: the ADS-B labelling state does not load "
                                  f"({type(exc).__name__}: {exc})") from None
    return tracker, labeler
