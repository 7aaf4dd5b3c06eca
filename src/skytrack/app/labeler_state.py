"""The ADS-B labeller's whole state as plain arrays and JSON, and a labeller rebuilt from them
(issue 11 item 3: checkpoints keep the identification pairs of a live service).

:func:`labeler_state` turns a :class:`~skytrack.app.identification.TrackLabeler` into a flat
``{name: numpy array}`` dict (no pickle): the identifier's track and pair filter banks (the pairs'
joint filters, sequential test statistics, degrees of freedom, update counts), its track keys,
the other system's reports, and a ``meta`` array holding, as JSON, everything else — the
labels held, the generations and last reports of every track, the decisions log, the statistics.
Python containers are written with their type (tuple, set, dict with integer or text keys) so that
:meth:`TrackLabeler.restore <skytrack.app.identification.TrackLabeler.restore>` rebuilds them exactly
(:func:`read_labeler_state`, :func:`restore_identifier`); the model and the configurations are rebuilt from
the saved :class:`~skytrack.app.identification.AdsbIdentificationConfig`.  A restored labeller
labels the same track rows as the original (tests/app/test_app_checkpoint.py).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

#: version of this layout; another version is refused
LABELER_STATE_FORMAT = 1
#: attributes rebuilt from the configuration, not saved
REBUILT = frozenset({"model", "config", "kernel_q"})


def _plain(value):
    """A numpy scalar as the Python value it holds."""
    if isinstance(value, np.generic):
        return value.item()
    return value


def _encode(value, path: str, arrays: dict[str, np.ndarray]):
    """JSON of ``value`` with container types kept (every container is a tagged list); numeric
    arrays go to ``arrays`` under ``path`` and are referred to by it."""
    value = _plain(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            return ["objects", [_encode(v, path, arrays) for v in value.tolist()]]
        arrays[path] = value.copy()
        return ["array", path]
    if isinstance(value, dict):
        return ["dict", [[_encode(k, f"{path}.key{i}", arrays), _encode(v, f"{path}.{i}", arrays)]
                         for i, (k, v) in enumerate(value.items())]]
    for kind in (tuple, list, set):
        if isinstance(value, kind):
            items = sorted(value, key=repr) if kind is set else value
            return [kind.__name__, [_encode(v, f"{path}.{i}", arrays) for i, v in enumerate(items)]]
    if dataclasses.is_dataclass(value):
        return ["fields", {f.name: _encode(getattr(value, f.name), f"{path}.{f.name}", arrays)
                           for f in dataclasses.fields(value)}]
    raise TypeError(f"labeller state: {path} is a {type(value).__name__}, which a checkpoint cannot hold")


def _decode(value, arrays: dict[str, np.ndarray]):
    if not isinstance(value, list):
        return value
    kind, items = value
    if kind == "array":
        return np.array(arrays[items])
    if kind == "objects":
        out = np.empty(len(items), dtype=object)
        out[:] = [_decode(v, arrays) for v in items]
        return out
    if kind == "dict":
        return {_decode(k, arrays): _decode(v, arrays) for k, v in items}
    if kind == "fields":
        return {name: _decode(v, arrays) for name, v in items.items()}
    decoded = [_decode(v, arrays) for v in items]
    return {"tuple": tuple, "list": list, "set": set}[kind](decoded)


def _walk(obj, path: str, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """Every attribute of ``obj`` except the rebuilt ones: objects of skytrack's own classes
    (filter banks, pair banks) attribute by attribute, the rest encoded."""
    for name, value in vars(obj).items():
        if name in REBUILT:
            continue
        key = f"{path}.{name}"
        if type(value).__module__.startswith("skytrack.identify") and hasattr(value, "__dict__"):
            meta[key] = ["object", None]
            _walk(value, key, arrays, meta)
        else:
            meta[key] = _encode(value, key, arrays)


def labeler_state(labeler) -> dict[str, np.ndarray]:
    """The labeller's state as a flat dict of arrays (``meta``: the JSON part, as bytes)."""
    arrays: dict[str, np.ndarray] = {}
    meta: dict = {}
    _walk(labeler.identifier, "identifier", arrays, meta)
    other = {f.name: _encode(getattr(labeler.other, f.name), f"other.{f.name}", arrays)
             for f in dataclasses.fields(labeler.other)}
    rest = {name: _encode(value, name, arrays) for name, value in vars(labeler).items()
            if name not in ("config", "identifier", "other")}
    header = {"format": LABELER_STATE_FORMAT, "config": dataclasses.asdict(labeler.config), "other": other,
              "identifier": meta, "labeler": rest}
    arrays["meta"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    return arrays


def read_labeler_state(state: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict]:
    """What :func:`labeler_state` saved, decoded: ``(config fields, other system's fields, the
    labeller's other attributes, the identifier's entries)``; the last go to
    :func:`restore_identifier` (raises ``ValueError`` for another format)."""
    header = json.loads(np.asarray(state["meta"], np.uint8).tobytes().decode())
    if header.get("format") != LABELER_STATE_FORMAT:
        raise ValueError(f"labeller state format {header.get('format')!r} is not {LABELER_STATE_FORMAT}")
    other = {name: _decode(value, state) for name, value in header["other"].items()}
    rest = {name: _decode(value, state) for name, value in header["labeler"].items()}
    return header["config"], other, rest, header["identifier"]


def restore_identifier(identifier, entries: dict, state: dict[str, np.ndarray]) -> None:
    """Write the identifier's saved ``entries`` into ``identifier``, newly built from the same
    configuration."""
    for key, value in entries.items():
        parts = key.split(".")[1:]
        owner = identifier
        for part in parts[:-1]:
            owner = getattr(owner, part)
        if value == ["object", None]:
            if getattr(owner, parts[-1]) is None:
                raise ValueError(f"labeller state has {key}, which this configuration does not make")
            continue
        setattr(owner, parts[-1], _decode(value, state))
