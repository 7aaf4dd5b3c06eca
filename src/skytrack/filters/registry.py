"""Registry of filter families: a kind name -> a factory building the filter from a motion model.

Adding a family is one module in ``skytrack/filters/`` with a ``@register_filter("kind")``
factory: every module of the package is imported when this registry is first imported
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
FILTERS: dict[str, FilterFactory] = {}


def register_filter(kind: str) -> Callable[[FilterFactory], FilterFactory]:
    def decorate(factory: FilterFactory) -> FilterFactory:
        if kind in FILTERS:
            raise ValueError(f"filter kind {kind!r} is registered twice")
        FILTERS[kind] = factory
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


_discover_families()
