"""Write a simulated dataset as the files ``hmmtrack track`` and ``hmmtrack sync`` read.

:func:`write_scenario` writes a :class:`~hmmtrack.scenarios.Scenario`:

``detections.csv`` (``time`` ISO 8601 UTC with milliseconds, ``receiver``, ``transmitter``,
``depth`` for a depth tag), ``receivers.csv`` (``receiver``, ``time`` — empty for a moored
hydrophone —, ``x``, ``y`` in m), ``truth.csv`` (``time``, ``x``, ``y``, ``depth``) and
``scenario.json`` (name, description, the tracker's settings the caller gives, the file
names); metres to the millimetre.
Times are printed by :func:`hmmtrack.io.format_times`; milliseconds are what real receivers
log, so the files carry up to 0.5 ms (0.73 m of range) of rounding that the in-memory
scenario does not.

:func:`write_tagged_array` writes a :class:`~hmmtrack.scenarios.array.TaggedArray` (a moored
array with unsynchronised clocks, sync tags and a pseudo-random-interval tag): the files of
:data:`ARRAY_FILE_NAMES`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io import format_times
from hmmtrack.scenarios.array import TaggedArray
from hmmtrack.scenarios.scenario import Scenario

#: file names written by :func:`write_scenario`, by table
FILE_NAMES = {
    "detections": "detections.csv",
    "receivers": "receivers.csv",
    "truth": "truth.csv",
    "metadata": "scenario.json",
}


def _file_paths(directory: str | Path, names: Mapping[str, str]) -> dict[str, Path]:
    """The paths of ``names`` (key -> file name) in ``directory``, created if needed."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    return {key: directory / name for key, name in names.items()}


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
    paths = _file_paths(directory, FILE_NAMES)
    for key in ("detections", "receivers", "truth"):
        _with_iso_times(getattr(scenario, key)).to_csv(paths[key], index=False, float_format="%.3f")
    metadata = {"name": scenario.name, "description": scenario.description, **settings} | {
        "files": {key: name for key, name in FILE_NAMES.items() if key != "metadata"},
        "synthetic": True,
    }
    paths["metadata"].write_text(json.dumps(metadata, indent=2) + "\n")
    return paths


#: file names written by :func:`write_tagged_array`, by table
ARRAY_FILE_NAMES = {
    "detections": "detections.csv",
    "receivers": "receivers.csv",
    "truth": "truth.csv",
    "receivers_truth": "receivers_truth.csv",
    "emissions": "emissions.csv",
    "burst_sequence": "burst_sequence.csv",
    "metadata": "scenario.json",
}


def write_tagged_array(case: TaggedArray, directory: str | Path) -> dict[str, Path]:
    """Write a moored array with a tag into ``directory`` (created if needed).

    * ``detections.csv`` - ``time`` (ISO 8601 UTC to the millisecond, as receivers log it,
      each receiver's own clock), ``receiver``, ``transmitter``: the sync tags and the tag,
      echoes included;
    * ``receivers.csv`` - the receivers file of ``hmmtrack sync``: ``receiver``, ``x``,
      ``y``, ``z`` (m, surveyed), ``sync_tag``, ``fixed``;
    * ``truth.csv`` - the tag's path every second: ``time`` (ISO, true UTC), ``x``, ``y``;
    * ``receivers_truth.csv`` - true ``x``, ``y``, ``z`` and clock of every receiver:
      ``clock_offset_s``, ``clock_drift_ppm``, ``clock_drift_rate_ppm_per_day``,
      ``clock_reference_time`` (epoch s; :class:`~hmmtrack.scenarios.array.DriftingClock`);
    * ``emissions.csv`` - ``ping``, true ``emission_time`` (epoch s to the microsecond),
      ``sequence_index`` (the index in the burst sequence of the interval after it);
    * ``burst_sequence.csv`` - ``interval`` (s): the tag's interval sequence, in the order
      it uses them, cyclically;
    * ``scenario.json`` - name, description, the files and the tag's ``transmitter`` (no
      measurement: a ``--config`` layer under ``hmmtrack track``'s options).

    Returns
    -------
    dict of str to Path
        The files written, keyed like :data:`ARRAY_FILE_NAMES`.
    """
    paths = _file_paths(directory, ARRAY_FILE_NAMES)
    array = case.array
    _with_iso_times(case.detections).to_csv(paths["detections"], index=False)
    receivers = array.receivers[["receiver", "x", "y", "z", "sync_tag", "fixed"]]
    receivers.to_csv(paths["receivers"], index=False, float_format="%.3f")
    _with_iso_times(case.truth).to_csv(paths["truth"], index=False, float_format="%.3f")
    truth = array.receivers_truth.copy()
    for column, field in (
        ("clock_offset_s", "offset"),
        ("clock_drift_ppm", "drift_ppm"),
        ("clock_drift_rate_ppm_per_day", "drift_rate_ppm_per_day"),
        ("clock_reference_time", "reference_time"),
    ):
        truth[column] = [getattr(array.clocks[name], field) for name in truth["receiver"]]
    truth.to_csv(paths["receivers_truth"], index=False)
    n = case.emission_times.size
    pd.DataFrame(
        {
            "ping": np.arange(n),
            "emission_time": case.emission_times,
            "sequence_index": (case.first_index + np.arange(n)) % case.sequence.size,
        }
    ).to_csv(paths["emissions"], index=False, float_format="%.6f")
    pd.DataFrame({"interval": case.sequence}).to_csv(
        paths["burst_sequence"], index=False, float_format="%.6f"
    )
    low, high = case.burst_interval
    metadata = {
        "name": "moored-array",
        "description": (
            f"Synthetic: a tag moving inside a moored array of {len(receivers)} receivers "
            f"with unsynchronised clocks and sync tags, pinging at a pseudo-random burst "
            f"interval in [{low:g}, {high:g}] s (its sequence in burst_sequence.csv); detections "
            "in each receiver's clock, with multipath and echoes. truth.csv is in true UTC: "
            "receivers_truth.csv holds the clocks that map it to a time keeper's."
        ),
        "transmitter": case.transmitter,
        "files": {key: name for key, name in ARRAY_FILE_NAMES.items() if key != "metadata"},
        "synthetic": True,
    }
    paths["metadata"].write_text(json.dumps(metadata, indent=2) + "\n")
    return paths
