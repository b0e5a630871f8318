"""Golden runs: fixed-seed tracking runs whose outputs a refactor must leave as they are.

Each case is one function below that builds its inputs from a synthetic scenario with a
fixed seed, runs the public tracking API and returns ``{table name: DataFrame}``. The
stored outputs are ``tests/data/golden/<case>/<table>.csv`` (written by
``tests/make_golden.py``); ``tests/test_golden.py`` recomputes every case and requires the
same columns, the same shape and the same values (NaN equal to NaN; floats to within
:data:`ACROSS_MACHINES` of their column's scale when recomputed on another machine).

Inputs go scenario → detections table + receiver positions table → public call, so that
a refactor of the trackers changes only the tracking calls of this file (their imports
and signatures), never what goes into them. The inputs themselves are two cases too
(:func:`inputs_range_rate`, :func:`inputs_arrival_time`): when a tracking case differs,
they tell whether the scenario or the tracker changed.

Every run names the paper's filter (:data:`FILTER`), so that a change of the library's
default filter (:data:`hmmtrack.tracking.filter.DEFAULT_FILTER`) leaves these runs as they
are. The cases:

* range-rate tracking (:func:`hmmtrack.tracking.pipeline.track`) of the first 20 minutes of the
  shark pursuit (:func:`hmmtrack.scenarios.shark_pursuit`, two moving AUVs), 1,000
  particles, with each motion model: baseline, velocity, the bundled white-shark HMM
  (time-consistent, with its default resting state) and the HMM in the paper's variant
  with the paper's resampling (multinomial, after every correction); and the velocity
  motion under the ``range-rate-gps`` measurement (its GPS offsets integrated out, and the
  velocity model that measurement fills in: :data:`hmmtrack.tracking.motion.VELOCITY_GPS`);
* arrival-time tracking (:func:`hmmtrack.tracking.pipeline.track` with
  ``measurement="arrival-time"``) of 20 minutes
  of the moored array (:func:`hmmtrack.scenarios.realistic.moored_array`, three moorings,
  wandering tag clock, multipath), 1,000 particles: plain (bundled HMM), with a fixed-lag
  smoother (velocity motion), with a detection curve counting silences (velocity motion).

Nothing here depends on the number of threads: the compiled filter gives one answer
whatever it is (:class:`hmmtrack.tracking.filter.ParticleFilter`; at 1,000 particles its kernels
run one chunk, on one thread, anyway), so the calls are the default public ones. Checked
by hand: the same tables with ``NUMBA_NUM_THREADS=1`` and with every compiled call forced
onto two threads.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack import scenarios
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.measurement.detection import LogisticDetection

#: folder of the stored outputs: one sub-folder per case, one CSV per table
GOLDEN_DIR = Path(__file__).parent / "data" / "golden"

#: particles of every run
N_PARTICLES = 1000
#: the filter of every run, named (:data:`hmmtrack.tracking.filter.FILTERS`): the paper's,
#: whatever the library's default filter is
FILTER = "paper"
#: seconds tracked from each scenario's start
SPAN = 1200.0
#: seed of the range-rate scenario (the shark pursuit; on seed 5 the velocity and HMM runs
#: end within 10 m of the truth, the baseline and the paper's variant do not)
PURSUIT_SEED = 5
#: seed of the arrival-time scenario (the moored array)
MOORED_SEED = 5
#: seed of every tracking run
TRACK_SEED = 3
#: seconds after the start at which range-rate runs keep a snapshot of their particles
SNAPSHOT_AFTER = 600.0
#: receiver positions kept after the last detection of the range-rate inputs (s)
RECEIVER_MARGIN = 60.0
#: steps of the fixed-lag smoother of :func:`arrival_time_smoothed`
SMOOTHING_LAG = 30
#: detection curve of :func:`arrival_time_silence`: the moored array's own (1.75 and 0.25
#: array radii, the radius 400 m for :data:`MOORED_SEED`), written out
DETECTION = LogisticDetection(range_50=700.0, width=100.0)


# ---------------------------------------------------------------------------- inputs


def range_rate_inputs() -> tuple[pd.DataFrame, pd.DataFrame, TrackingConfig]:
    """Detections, receiver positions and configuration of the range-rate cases.

    The shark pursuit of :data:`PURSUIT_SEED` cut to its first :data:`SPAN` seconds:
    detections up to ``start + SPAN``, AUV positions up to :data:`RECEIVER_MARGIN` later.

    Returns
    -------
    detections : pandas.DataFrame
        ``time`` (s), ``receiver``, ``transmitter``.
    receivers : pandas.DataFrame
        ``receiver``, ``time`` (s), ``x``, ``y`` (m).
    config : TrackingConfig
        The scenario's period, true ``r0``, sound speed, transmitter and window; search
        bounds from ``r0`` (``bounds=None``), :data:`N_PARTICLES`, the :data:`FILTER`, other
        settings default.
    """
    sc = scenarios.shark_pursuit(PURSUIT_SEED)
    end = sc.start + SPAN
    detections = sc.detections[sc.detections["time"] <= end].reset_index(drop=True)
    receivers = sc.receivers[sc.receivers["time"] <= end + RECEIVER_MARGIN].reset_index(drop=True)
    config = TrackingConfig.from_keys(
        period=sc.period,
        r0=dict(sc.r0),
        sound_speed=sc.sound_speed,
        transmitter=sc.transmitter,
        start=sc.start,
        end=end,
        n_particles=N_PARTICLES,
        filter=FILTER,
    )
    return detections, receivers, config


def arrival_time_inputs() -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Detections, receiver positions and window of the arrival-time cases.

    The moored array of :data:`MOORED_SEED`, :data:`SPAN` seconds long, its detections on
    the common time base (the calibrated receiver clocks applied).

    Returns
    -------
    detections : pandas.DataFrame
        ``time`` (s, common time base), ``receiver``, ``transmitter``.
    receivers : pandas.DataFrame
        ``receiver``, ``time`` (NaN: moored), ``x``, ``y`` (m).
    options : dict
        ``period`` (the scenario's mean period, s), ``start`` and ``end`` (s).
    """
    case = moored_array(MOORED_SEED, duration=SPAN)
    sc = case.scenario
    options = {"period": sc.period, "start": sc.start, "end": sc.end}
    return case.corrected_detections(), sc.receivers, options


def inputs_range_rate() -> dict[str, pd.DataFrame]:
    """The inputs of the range-rate cases (:func:`range_rate_inputs`)."""
    detections, receivers, _ = range_rate_inputs()
    return {"detections": detections, "receivers": receivers}


def inputs_arrival_time() -> dict[str, pd.DataFrame]:
    """The inputs of the arrival-time cases (:func:`arrival_time_inputs`)."""
    detections, receivers, _ = arrival_time_inputs()
    return {"detections": detections, "receivers": receivers}


# ---------------------------------------------------------------------------- range-rate


def _range_rate_tables(result) -> dict[str, pd.DataFrame]:
    """Every table of a :class:`hmmtrack.tracking.pipeline.TrackingResult`."""
    (snapshot,) = result.snapshots.values()
    return {
        "estimates": result.estimates,
        "events": result.events,
        "observations": result.observations,
        "snapshot": snapshot,
        "bounds": pd.DataFrame([result.bounds], columns=["xmin", "xmax", "ymin", "ymax"]),
    }


def _track_range_rate(**changes) -> dict[str, pd.DataFrame]:
    detections, receivers, config = range_rate_inputs()
    result = tracking.track(
        detections,
        receivers,
        config.override(**changes),
        seed=TRACK_SEED,
        snapshot_times=(config.start + SNAPSHOT_AFTER,),
    )
    return _range_rate_tables(result)


def range_rate_baseline() -> dict[str, pd.DataFrame]:
    """Range-rate tracking, baseline motion (random walk)."""
    return _track_range_rate(motion="baseline")


def range_rate_velocity() -> dict[str, pd.DataFrame]:
    """Range-rate tracking, velocity motion."""
    return _track_range_rate(motion="velocity")


def range_rate_gps_velocity() -> dict[str, pd.DataFrame]:
    """Range-rate tracking under ``range-rate-gps`` (each receiver's GPS error an offset
    integrated out per particle), velocity motion with that measurement's settings
    (:data:`hmmtrack.tracking.motion.VELOCITY_GPS`: speed jumps and a still regime)."""
    return _track_range_rate(motion="velocity", measurement="range-rate-gps")


def range_rate_hmm() -> dict[str, pd.DataFrame]:
    """Range-rate tracking, the bundled HMM (time-consistent, default resting state)."""
    return _track_range_rate(motion="hmm")


def range_rate_hmm_paper() -> dict[str, pd.DataFrame]:
    """Range-rate tracking, the bundled HMM in the paper's variant (no resting state) with
    the paper's resampling: multinomial, after every correction."""
    return _track_range_rate(
        motion="hmm", variant="paper", resampling="multinomial", resample_when="always"
    )


# ---------------------------------------------------------------------------- arrival-time


def _arrival_time_tables(result) -> dict[str, pd.DataFrame]:
    """Every arrival-time table of a :class:`hmmtrack.tracking.pipeline.TrackingResult`
    (``smoothed`` when there is one; no snapshots are asked for)."""
    tables = {
        "estimates": result.estimates,
        "events": result.events,
        "ambiguity": result.ambiguity,
        "clock": result.clock,
    }
    if result.smoothed is not None:
        tables["smoothed"] = result.smoothed
    return tables


def _track_arrival_time(**settings) -> dict[str, pd.DataFrame]:
    detections, receivers, window = arrival_time_inputs()
    config = TrackingConfig.from_keys(
        measurement="arrival-time", n_particles=N_PARTICLES, filter=FILTER, **window, **settings
    )
    result = tracking.track(detections, receivers, config, seed=TRACK_SEED)
    return _arrival_time_tables(result)


def arrival_time_plain() -> dict[str, pd.DataFrame]:
    """Arrival-time tracking, the bundled HMM (time-consistent, default resting state)."""
    return _track_arrival_time(motion="hmm")


def arrival_time_smoothed() -> dict[str, pd.DataFrame]:
    """Arrival-time tracking, velocity motion, fixed-lag smoother of :data:`SMOOTHING_LAG`."""
    return _track_arrival_time(
        motion="velocity", sigma_speed=0.05, sigma_turn_rate=0.02, smoothing_lag=SMOOTHING_LAG
    )


def arrival_time_silence() -> dict[str, pd.DataFrame]:
    """Arrival-time tracking, velocity motion, unheard pings scored with :data:`DETECTION`."""
    return _track_arrival_time(
        motion="velocity", sigma_speed=0.05, sigma_turn_rate=0.02, detection_curve=DETECTION
    )


#: every golden case by name (the name of its folder in :data:`GOLDEN_DIR`)
CASES: dict[str, Callable[[], dict[str, pd.DataFrame]]] = {
    f.__name__: f
    for f in (
        inputs_range_rate,
        inputs_arrival_time,
        range_rate_baseline,
        range_rate_velocity,
        range_rate_gps_velocity,
        range_rate_hmm,
        range_rate_hmm_paper,
        arrival_time_plain,
        arrival_time_smoothed,
        arrival_time_silence,
    )
}


# ---------------------------------------------------------------------------- storage


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Write ``table`` without its index; floats as their shortest round-trip text."""
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False, lineterminator="\n")


def read_table(path: Path) -> pd.DataFrame:
    """Read a table of :func:`write_table` back, floats parsed exactly.

    pandas infers the columns' types; float columns are then parsed again from their text
    by Python's ``float`` (correctly rounded, so exact for shortest round-trip text on any
    pandas version), an empty field as NaN.
    """
    table = pd.read_csv(path)
    text = pd.read_csv(path, dtype=str, keep_default_na=False)
    for column in table.columns:
        if table[column].dtype.kind == "f":
            table[column] = np.array([float(v) if v else np.nan for v in text[column]])
    return table


def read_case(case: str, folder: Path = GOLDEN_DIR) -> dict[str, pd.DataFrame]:
    """The stored tables of ``case``, by name."""
    return {path.stem: read_table(path) for path in sorted((folder / case).glob("*.csv"))}


def _kind(column: pd.Series) -> str:
    """``"bool"``, ``"int"``, ``"float"`` or ``"text"``."""
    return {"b": "bool", "i": "int", "u": "int", "f": "float"}.get(column.dtype.kind, "text")


def _text(column: pd.Series) -> list[str]:
    """Values as strings, a missing value (None, NaN) as the empty string (as CSV has it)."""
    return ["" if pd.isna(v) else str(v) for v in column.tolist()]


#: the tolerance of :func:`differences` when the runs are recomputed on another machine or
#: with other library versions than the stored ones: the filter's sums are vectorised with
#: the CPU's lane count (``fastmath={"reassoc"}``) and NumPy's and libm's transcendental
#: functions change in their last bits between releases and instruction sets, so answers
#: agree to about 1e-15 of a column's scale there, not bit for bit. A changed answer
#: (another draw, another formula) moves them by far more than this. Bits are checked
#: before and after a change on one machine (``benchmarks/run_hashes.py``, ``rtol = 0``).
ACROSS_MACHINES = 1e-9


def differences(
    expected: pd.DataFrame, actual: pd.DataFrame, name: str, rtol: float = 0.0
) -> list[str]:
    """What differs between a stored table and a recomputed one (empty when nothing).

    Columns must be the same, in the same order, and the shapes equal. Numeric columns
    (bool, int, float) must hold the same kind of number and, with ``rtol = 0``, exactly
    the same numbers (NaN equal to NaN); with ``rtol > 0``, float columns may differ by up
    to ``rtol`` times the column's largest stored magnitude (:data:`ACROSS_MACHINES`).
    Other columns must hold the same text.

    Parameters
    ----------
    expected, actual : pandas.DataFrame
        Stored and recomputed table.
    name : str
        Named in the messages.
    rtol : float
        Tolerance of float columns, relative to each column's largest finite stored
        magnitude; 0 asks for the same bits.

    Returns
    -------
    list of str
        One message per difference found.
    """
    if list(expected.columns) != list(actual.columns):
        return [f"{name}: columns {list(actual.columns)}, stored {list(expected.columns)}"]
    if expected.shape != actual.shape:
        return [f"{name}: shape {actual.shape}, stored {expected.shape}"]
    found = []
    for column in expected.columns:
        e, a = expected[column], actual[column]
        kinds = _kind(e), _kind(a)
        if len(e) and kinds[0] != kinds[1]:
            found.append(f"{name}.{column}: {kinds[1]} values, stored {kinds[0]}")
        elif "text" not in kinds:
            e_values, a_values = e.to_numpy(dtype=float), a.to_numpy(dtype=float)
            if not np.array_equal(e_values, a_values, equal_nan=True):
                same = (e_values == a_values) | (np.isnan(e_values) & np.isnan(a_values))
                if rtol > 0 and "float" in kinds:
                    finite = np.abs(e_values[np.isfinite(e_values)])
                    scale = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
                    same |= np.abs(a_values - e_values) <= rtol * scale
                if same.all():
                    continue
                rows = np.flatnonzero(~same)
                first = rows[0]
                gaps = np.abs(a_values[rows] - e_values[rows])
                gaps = gaps[np.isfinite(gaps)]
                largest = float(gaps.max()) if gaps.size else float("nan")
                found.append(
                    f"{name}.{column}: {rows.size} of {len(e)} values differ, first at row "
                    f"{first} ({float(a_values[first])!r}, stored {float(e_values[first])!r}), "
                    f"largest finite difference {largest!r}"
                )
        else:
            e_text, a_text = _text(e), _text(a)
            if e_text != a_text:
                row = next(k for k, (u, v) in enumerate(zip(e_text, a_text, strict=True)) if u != v)
                found.append(
                    f"{name}.{column}: text differs, first at row {row} "
                    f"({a_text[row]!r}, stored {e_text[row]!r})"
                )
    return found
