"""Markdown pieces of the reports: numbers as we print them, the paper's as it printed them,
and pipe tables."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd


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


def frame_markdown(table: pd.DataFrame) -> str:
    """A pipe table of ``table``'s columns (no index): floats with 3 significant digits
    below 10 and one decimal from 10 on, everything else as text."""
    cells = table.map(
        lambda v: (f"{v:.1f}" if abs(v) >= 10 else f"{v:.3g}") if isinstance(v, float) else str(v)
    )
    return markdown_table(list(map(str, table.columns)), cells.to_numpy().tolist())


def indexed_markdown(frame: pd.DataFrame) -> str:
    """A pipe table of ``frame`` with its index first, floats with 2 decimals."""

    def cell(value) -> str:
        if isinstance(value, tuple):
            return " ".join(map(str, value))
        return f"{value:.2f}" if isinstance(value, float) else str(value)

    values = frame.astype(object).to_numpy()  # integer columns stay integers
    rows = [[cell(i), *map(cell, row)] for i, row in zip(frame.index, values, strict=True)]
    names = frame.index.names if frame.index.nlevels > 1 else [frame.index.name]
    return markdown_table([" ".join(str(n or "") for n in names), *map(str, frame.columns)], rows)
