"""The machine a benchmark ran on: CPU model, cores and load, printed beside its timings.

Timings from different runs are only comparable on the same machine at the same load, so
every benchmark prints :func:`describe` at its start and end and compares filters by
ratios measured in the same run.
"""

from __future__ import annotations

import os
import platform


def cpu_model() -> str:
    """The CPU's model name (from ``/proc/cpuinfo`` on Linux, else :mod:`platform`)."""
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def describe(when: str) -> str:
    """``"machine at start: <CPU>, N cores, load a / b / c"`` (1, 5, 15-minute averages)."""
    load = " / ".join(f"{value:.2f}" for value in os.getloadavg())
    return f"machine at {when}: {cpu_model()}, {os.cpu_count()} cores, load {load}"
