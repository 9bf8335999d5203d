"""Small checks the sections' ``check`` methods share, each refusing with
:class:`~mjx_surrogate.errors.ConfigError` naming the field."""

from __future__ import annotations

import math
from typing import Any

from mjx_surrogate.errors import ConfigError


def at_least(lowest: int, fields: dict) -> None:
    """Each integer field >= ``lowest``."""
    for field, v in fields.items():
        if v < lowest:
            raise ConfigError(field, f"must be >= {lowest}, got {v}")


def nonnegative(fields: dict) -> None:
    """Each field a finite number >= 0."""
    for field, v in fields.items():
        if not (math.isfinite(v) and v >= 0):
            raise ConfigError(field, f"must be a finite number >= 0, got {v}")


def check_finite(field: str, values: Any) -> None:
    """Raise if a (nested) sequence of numbers holds NaN or inf."""
    flat = (
        values
        if not values or not isinstance(values[0], (list, tuple))
        else [v for row in values for v in row]
    )
    for v in flat:
        if not math.isfinite(v):
            raise ConfigError(field, f"holds a non-finite value ({v}); all entries must be finite")
