"""Checks of scenario-file values shared by the world and the sensors."""
from __future__ import annotations

import math


def number_rows(value, width: int, field: str, shape: str) -> tuple[tuple[float, ...], ...]:
    """A scenario file's list of rows of ``width`` finite numbers (fault windows and the
    like) as a tuple of float tuples; ValueError naming the field and the row shape."""
    try:
        rows = tuple(tuple(float(v) for v in row) for row in value)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a list of {shape} rows of numbers") from None
    if any(len(row) != width or not all(math.isfinite(v) for v in row) for row in rows):
        raise ValueError(f"{field} must be a list of {shape} rows of finite numbers")
    return rows
