"""How the command lines write numbers and counts for people: plurals, lengths in a unit of their size,
short lists.

These are for the lines printed on stdout and stderr; the files (CSV, JSON) keep SI units and full precision.
"""

from __future__ import annotations

import math


def plural(count, word: str, words: str | None = None) -> str:
    """``"1 travel"``, ``"3 travels"`` (``words``: the plural when it is not ``word + "s"``)."""
    return f"{count} {word if count == 1 else (words or word + 's')}"


def length(metres: float, digits: int = 3) -> str:
    """A length in the unit of its size: ``"3.2 mm"``, ``"4.51 cm"``, ``"70 m"``, ``"12.3 km"``.

    Args:
        metres: the length [m].
        digits: significant digits.
    """
    if not math.isfinite(metres):
        return f"{metres} m"
    size = abs(metres)
    for unit, scale, below in (("mm", 1e-3, 1e-2), ("cm", 1e-2, 1.0), ("m", 1.0, 1e4), ("km", 1e3, math.inf)):
        if size < below or unit == "km":
            return f"{metres / scale:.{digits}g} {unit}"
    return f"{metres:.{digits}g} m"  # pragma: no cover - the loop always returns


def number(value, digits: int = 6) -> str:
    """A number as a person reads it: integers as they are, floats with ``digits`` significant digits."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}g}"


def short_list(values, digits: int = 6, head: int = 4, tail: int = 2) -> str:
    """``values`` separated by commas, with the middle of a long list left out (``1,2,3,4,...,9,10 (10 values)``)."""
    values = list(values)
    shown = [number(v, digits) for v in values]
    if len(shown) <= head + tail + 1:
        return ",".join(shown)
    return ",".join(shown[:head] + ["..."] + shown[-tail:]) + f" ({len(shown)} values)"
