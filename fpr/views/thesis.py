"""The thesis beside the toolkit: a table of the thesis' claims and what this package finds (notebooks 01-05).

Each notebook ends with a :class:`Claim` per claim or figure of the thesis it reproduces: a few words with the
section or figure number, the thesis' value where it gives one (typed, from the thesis' text), ours (always
computed by the notebook, never typed), whether they agree, and why not when they do not, backed by a
number the notebook computes. :func:`claims_markdown` renders them for ``IPython.display.Markdown``;
:func:`fmt` rounds numbers for such tables.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fpr.model.errors import ModelArgumentError


def fmt(value, digits: int = 3, unit: str = "") -> str:
    """``value`` rounded to ``digits`` significant digits, with thousands separators for large numbers
    (557683.9 -> "557,684"), integers as they are, numbers below 1e-3 in scientific notation (2.1e-14), and
    ``unit`` after a space; text is returned as it is.

    Args:
        value: a number (or text).
        digits: significant digits kept (at least the integer part of a number >= 10^digits).
        unit: appended after a space when not empty.
    """
    if isinstance(value, str):
        text = value
    elif isinstance(value, (bool, np.bool_)):
        text = "yes" if value else "no"
    elif isinstance(value, (int, np.integer)):
        text = f"{int(value):,}"
    else:
        x = float(value)
        if not math.isfinite(x):
            text = str(x)
        elif x == 0:
            text = "0"
        elif abs(x) < 1e-3:  # tiny: scientific, not a row of zeros
            text = f"{x:.{max(digits - 1, 0)}e}"
        elif abs(x) >= 10 ** digits:
            text = f"{round(x):,}"
        else:
            decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
            text = f"{x:,.{decimals}f}"
    return f"{text} {unit}".rstrip() if unit else text


@dataclass(frozen=True)
class Claim:
    """One claim or figure of the thesis, beside what this package finds.

    Attributes:
        claim: what the thesis says or shows, in a few words.
        where: its section or figure number (e.g. "3.2.5, Fig. 3.7").
        thesis: the thesis' value or statement ("-" when it gives none), typed with its source.
        ours: our value, formatted from a number the notebook computed.
        agree: whether we find the same.
        why: when we do not agree: a short explanation, backed by a number the notebook computed (required
            when ``agree`` is False).
    """

    claim: str
    where: str
    thesis: str
    ours: str
    agree: bool
    why: str = ""

    def __post_init__(self):
        if not self.agree and not self.why.strip():
            raise ModelArgumentError("why", self.why, f"claim {self.claim!r} ({self.where}) disagrees with the "
                                                      "thesis: say why, with a number the notebook computed")


def claims_markdown(claims) -> str:
    """A Markdown table of ``claims`` (:class:`Claim`): claim, where, thesis, ours, agree, why."""
    def cell(text: str) -> str:
        return str(text).replace("|", "\\|").replace("\n", " ")

    lines = ["| thesis claim | where | thesis | ours | agree | why not |", "|---|---|---|---|---|---|"]
    for c in claims:
        lines.append("| " + " | ".join(cell(x) for x in (c.claim, c.where, c.thesis, c.ours,
                                                          "yes" if c.agree else "**no**", c.why)) + " |")
    return "\n".join(lines)


def disagreements(claims) -> list[Claim]:
    """The claims we do not agree with."""
    return [c for c in claims if not c.agree]
