"""Registry of filter families: a kind name -> a factory building the filter from a motion model.

Adding a family is one module in ``skytrack/filters/`` with a ``@register_filter("kind")``
factory: every module of the package is imported when :data:`FILTERS` is first read
(:func:`_discover_families`), so nothing else needs editing; the tracker's configuration,
the CLI's ``--filter`` option and the conformance suite all read :data:`FILTERS`.

A factory is called as ``factory(motion, **options)`` with the tracker's motion model
(:class:`~skytrack.models.motion.MotionModel`) and the options of the configuration's
``filter`` section.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable


import skytrack.filters

from skytrack.filters.base import BatchFilter
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.maneuver import ManoeuvreSwitchFilter
from skytrack.models.motion import MotionModel

FilterFactory = Callable[..., BatchFilter]


class FilterRegistry(dict):
    """kind -> factory; reading it first imports every family module (:func:`_discover_families`).

    Discovery waits for the first read so that importing one family module first (which imports
    this registry) never finds a sibling module half-initialised: by the first read every module
    that imports another has finished."""

    _discovered = False

    def _discover(self) -> None:
        if not FilterRegistry._discovered:
            FilterRegistry._discovered = True
            _discover_families()

    def __getitem__(self, kind):
        self._discover()
        return super().__getitem__(kind)

    def __contains__(self, kind) -> bool:
        self._discover()
        return super().__contains__(kind)

    def __iter__(self):
        self._discover()
        return super().__iter__()

    def __len__(self) -> int:
        self._discover()
        return super().__len__()

    def keys(self):
        self._discover()
        return super().keys()

    def items(self):
        self._discover()
        return super().items()

    def values(self):
        self._discover()
        return super().values()

    def get(self, kind, default=None):
        self._discover()
        return super().get(kind, default)


FILTERS: dict[str, FilterFactory] = FilterRegistry()


def register_filter(kind: str) -> Callable[[FilterFactory], FilterFactory]:
    def decorate(factory: FilterFactory) -> FilterFactory:
        if dict.__contains__(FILTERS, kind):
            raise ValueError(f"filter kind {kind!r} is registered twice")
        dict.__setitem__(FILTERS, kind, factory)
        return factory

    return decorate


def build_filter(kind: str, motion: MotionModel, **options) -> BatchFilter:
    """The filter of the given kind; unknown kinds and options raise ValueError naming the known ones."""
    if kind not in FILTERS:
        raise ValueError(f"unknown filter kind {kind!r}; registered: {', '.join(sorted(FILTERS))}")
    try:
        return FILTERS[kind](motion, **options)
    except TypeError as exc:
        raise ValueError(f"filter {kind!r}: {exc}") from None


@register_filter("kalman")
def _kalman(motion: MotionModel, form: str = "joseph", compiled: bool = True) -> KalmanFilter:
    return KalmanFilter(motion, form=form, compiled=compiled)


@register_filter("kalman-psi")
def _kalman_psi(motion: MotionModel, scale: float = 3000.0, on: float = 3.0, off: float = 1.2,
                memory: float = 0.5, compiled: bool = True) -> ManoeuvreSwitchFilter:
    return ManoeuvreSwitchFilter(KalmanFilter(motion, compiled=compiled), scale, on, off, memory)


def _discover_families() -> None:
    """Import every module of ``skytrack.filters`` so that their ``@register_filter`` factories run."""
    for info in pkgutil.iter_modules(skytrack.filters.__path__):
        if not info.ispkg and not info.name.startswith("_") and info.name != "registry":
            importlib.import_module(f"skytrack.filters.{info.name}")

