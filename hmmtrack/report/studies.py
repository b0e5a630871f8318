"""What every study report shares: how a study is timed, its provenance line, its kept reading.

Each study behind ``hmmtrack study NAME`` has its report module
(:mod:`~hmmtrack.report.stationary`, :mod:`~hmmtrack.report.clock_aware`,
:mod:`~hmmtrack.report.clock_bound`, :mod:`~hmmtrack.report.two_auv_plan`,
:mod:`~hmmtrack.report.closed_loop`) with one ``write_*`` function that runs the study
(:mod:`hmmtrack.experiments`), draws its figure (:mod:`hmmtrack.plots.studies`) and writes
its Markdown into a folder. A report that holds a hand-written reading after
:data:`READING_MARKER` keeps it when rewritten.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

#: the line after which a study report's hand-written reading starts; a rerun keeps it
READING_MARKER = "<!-- reading: kept when the script rewrites this file -->"


def run_timed(function, *args, **kwargs):
    """``function(*args, **kwargs)`` with its wall time and the machine's load.

    Returns
    -------
    value
        What ``function`` returned.
    seconds : float
        Wall time (s).
    load : (float, float)
        1-minute load average before and after (the machine is shared).
    """
    before = os.getloadavg()[0]
    tic = time.perf_counter()
    value = function(*args, **kwargs)
    return value, time.perf_counter() - tic, (before, os.getloadavg()[0])


def provenance(command: str, seconds: float, load: tuple[float, float]) -> str:
    """``Written by `command` in N s (1-minute load X at start, Y at end)``."""
    return (
        f"Written by `{command}` in {seconds:.0f} s (1-minute load {load[0]:.1f} at start, "
        f"{load[1]:.1f} at end)"
    )


def kept_reading(path: Path) -> str:
    """The hand-written reading of an existing report at ``path``: the text from
    :data:`READING_MARKER` on, marker included ("" when there is none)."""
    if not path.exists():
        return ""
    text = path.read_text()
    return text[text.index(READING_MARKER) :] if READING_MARKER in text else ""
