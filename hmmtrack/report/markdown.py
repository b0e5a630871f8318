"""Markdown pieces of the summary: numbers as we print them, the paper's as it printed them,
and pipe tables."""

from __future__ import annotations

import math
from collections.abc import Sequence


def fmt(value: float, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return f"{value:.{digits}g}" if abs(value) < 10**digits else f"{value:.0f}"


def paper_number(value: float) -> str:
    """A number of the paper, as the paper prints it."""
    return "–" if math.isnan(value) else f"{value:g}"


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)
