"""Value checks shared by the configuration sections (errors name the setting)."""

from __future__ import annotations

import math


def require_positive(section, *names: str) -> None:
    """Each named attribute must be finite and > 0."""
    for name in names:
        value = getattr(section, name)
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be finite and > 0, got {value}")


def require_non_negative(section, *names: str) -> None:
    """Each named attribute must be finite and >= 0."""
    for name in names:
        value = getattr(section, name)
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
