"""Write a :class:`~hmmtrack.scenarios.Scenario` as the files ``hmmtrack track`` reads.

``detections.csv`` (``time`` ISO 8601 UTC with milliseconds, ``receiver``, ``transmitter``,
``depth`` for a depth tag), ``receivers.csv`` (``receiver``, ``time`` — empty for a moored
hydrophone —, ``x``, ``y`` in m), ``truth.csv`` (``time``, ``x``, ``y``, ``depth``) and
``scenario.json`` (name, description, the tracker's settings the caller gives, the file
names); metres to the millimetre.
Times are printed by :func:`hmmtrack.io.format_times`; milliseconds are what real receivers
log, so the files carry up to 0.5 ms (0.73 m of range) of rounding that the in-memory
scenario does not.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io import format_times
from hmmtrack.scenarios.scenario import Scenario

#: file names written by :func:`write_scenario`, by table
FILE_NAMES = {
    "detections": "detections.csv",
    "receivers": "receivers.csv",
    "truth": "truth.csv",
    "metadata": "scenario.json",
}


def _with_iso_times(table: pd.DataFrame) -> pd.DataFrame:
    out = table.copy()
    times = out["time"].to_numpy(dtype=float)
    iso = np.full(times.size, "", dtype=object)
    timed = np.isfinite(times)
    iso[timed] = format_times(times[timed])
    out["time"] = iso
    return out


def write_scenario(scenario: Scenario, directory: str | Path, settings: Mapping) -> dict[str, Path]:
    """Write the scenario's tables and settings into ``directory`` (created if needed).

    Parameters
    ----------
    scenario : Scenario
    directory : str or Path
    settings : mapping
        JSON-ready tracking settings of the scenario written into ``scenario.json`` (this
        package does not know the tracker: see
        :func:`hmmtrack.experiments.configs.scenario_settings`).

    Returns
    -------
    dict of str to Path
        The files written, keyed like :data:`FILE_NAMES`.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = {key: directory / name for key, name in FILE_NAMES.items()}
    for key in ("detections", "receivers", "truth"):
        _with_iso_times(getattr(scenario, key)).to_csv(paths[key], index=False, float_format="%.3f")
    metadata = {"name": scenario.name, "description": scenario.description, **settings} | {
        "files": {key: name for key, name in FILE_NAMES.items() if key != "metadata"},
        "synthetic": True,
    }
    paths["metadata"].write_text(json.dumps(metadata, indent=2) + "\n")
    return paths
