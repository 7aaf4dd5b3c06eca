"""Strict reading of nested YAML/dict input with errors that name the key path.

Every value is read through a :class:`Fields` view of one mapping, which knows the path
of that mapping inside the document (``targets[3].legs[1]``) and the document's name
(``scenario.yaml``).  Errors read ``scenario.yaml: targets[3].legs[1].g: must be > 0,
got -2``.  Unknown keys are rejected with the list of known ones when the view is closed
with :meth:`Fields.finish`.
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from typing import Any

import yaml

_REQUIRED = object()
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message names the document and the key path."""


def join_path(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def describe(value: Any) -> str:
    return repr(value) if isinstance(value, str) else str(value)


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses duplicated mapping keys instead of keeping the last one."""

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, Any] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    "while constructing a mapping", node.start_mark, f"found duplicated key {key!r}", key_node.start_mark
                )
            seen[key] = True
        return super().construct_mapping(node, deep=deep)


def load_yaml(text: str, source: str) -> Any:
    """Parse YAML text; syntax errors become :class:`ScenarioError` with line and column."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f"{source}: line {mark.line + 1}, column {mark.column + 1}" if mark else source
        raise ScenarioError(f"{where}: {exc.problem or exc}") from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{source}: {exc}") from None


class Fields:
    """Typed, checked access to the keys of one mapping of the document."""

    def __init__(self, data: Any, path: str, source: str, known: tuple[str, ...]):
        self.path = path
        self.source = source
        self.known = known
        if not isinstance(data, dict):
            raise self.error_at(path, f"must be a mapping with keys {', '.join(known)}, got {describe(data)}")
        self.data = data
        self.finish()

    # -- errors ---------------------------------------------------------------
    def error_at(self, path: str, message: str) -> ScenarioError:
        return ScenarioError(f"{self.source}: {path or '(top level)'}: {message}")

    def error(self, key: str, message: str) -> ScenarioError:
        return self.error_at(join_path(self.path, key), message)

    def finish(self) -> None:
        for key in self.data:
            if key not in self.known:
                raise self.error(str(key), f"unknown key; known keys here: {', '.join(self.known)}")

    # -- access -----------------------------------------------------------------
    def has(self, key: str) -> bool:
        return self.data.get(key) is not None

    def raw(self, key: str, default: Any = _REQUIRED) -> Any:
        value = self.data.get(key)
        if value is None:
            if default is _REQUIRED:
                raise self.error(key, "required key is missing")
            return default
        return value

    def number(self, key: str, default: Any = _REQUIRED, *, gt=None, ge=None, lt=None, le=None) -> Any:
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return default
        return self.check_number(join_path(self.path, key), value, gt=gt, ge=ge, lt=lt, le=le)

    def check_number(self, path: str, value: Any, *, gt=None, ge=None, lt=None, le=None) -> float:
        if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 reads "250e3" as a string
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error_at(path, f"must be a number, got {describe(value)}")
        value = float(value)
        if not math.isfinite(value):
            raise self.error_at(path, f"must be finite, got {value}")
        for bound, ok, text in (
            (gt, lambda b: value > b, ">"),
            (ge, lambda b: value >= b, ">="),
            (lt, lambda b: value < b, "<"),
            (le, lambda b: value <= b, "<="),
        ):
            if bound is not None and not ok(bound):
                raise self.error_at(path, f"must be {text} {_fmt(bound)}, got {_fmt(value)}")
        return value

    def integer(self, key: str, default: Any = _REQUIRED, *, ge=None) -> Any:
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return default
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"must be an integer, got {describe(value)}")
        if ge is not None and value < ge:
            raise self.error(key, f"must be >= {ge}, got {value}")
        return int(value)

    def string(self, key: str, default: Any = _REQUIRED, *, choices: tuple[str, ...] | None = None) -> Any:
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return default
        if not isinstance(value, str):
            raise self.error(key, f"must be a string, got {describe(value)}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def boolean(self, key: str, default: Any = _REQUIRED) -> Any:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"must be true or false, got {describe(value)}")
        return value

    def interval(self, key: str, default: Any = _REQUIRED, *, ge=None, gt=None, le=None) -> Any:
        """A ``[low, high]`` pair with low <= high (a single number means [v, v])."""
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return default
        path = join_path(self.path, key)
        if not isinstance(value, list):
            value = [value, value]
        if len(value) != 2:
            raise self.error_at(path, f"must be a [low, high] pair, got {describe(value)}")
        low = self.check_number(join_path(path, 0), value[0], ge=ge, gt=gt, le=le)
        high = self.check_number(join_path(path, 1), value[1], ge=ge, gt=gt, le=le)
        if high < low:
            raise self.error_at(path, f"low must be <= high, got [{_fmt(low)}, {_fmt(high)}]")
        return (low, high)

    def items(self, key: str, default: Any = _REQUIRED) -> list[tuple[str, Any]]:
        """The elements of a list value with their paths."""
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return []
        if not isinstance(value, list):
            raise self.error(key, f"must be a list, got {describe(value)}")
        return [(join_path(join_path(self.path, key), i), item) for i, item in enumerate(value)]

    def sub(self, key: str, known: tuple[str, ...], default: Any = _REQUIRED) -> Fields | None:
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return None
        return Fields(value, join_path(self.path, key), self.source, known)

    def timestamp(self, key: str, default: Any = _REQUIRED) -> Any:
        """An ISO-8601 UTC instant, normalised to ``YYYY-MM-DDTHH:MM:SS[.ffffff]Z``."""
        value = self.raw(key, default)
        if value is default and default is not _REQUIRED:
            return default
        if isinstance(value, str):
            try:
                value = _dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
            except ValueError:
                raise self.error(key, f"must be an ISO-8601 UTC time such as 2021-10-07T12:00:00Z, got {value!r}") from None
        if isinstance(value, _dt.date) and not isinstance(value, _dt.datetime):
            value = _dt.datetime(value.year, value.month, value.day)
        if not isinstance(value, _dt.datetime):
            raise self.error(key, f"must be an ISO-8601 UTC time, got {describe(value)}")
        if value.tzinfo is not None:
            value = value.astimezone(_dt.timezone.utc).replace(tzinfo=None)
        return value.isoformat() + "Z"


def _fmt(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else repr(float(value))
