"""Fitted receiver clocks: the map from each receiver's time to the common time base, and
its file.

A receiver's clock runs early or late by a correction that changes slowly; in time segment
``k`` (starting at ``start_k``) the correction of a time ``t`` read on the receiver's own
clock is::

    correction(t) = offset_s + 1e-6 * (drift_ppm * u + 0.5 * drift_rate_ppm_per_day * u**2 / 86400)
    common(t) = t - correction(t),      u = t - start_k  (s)

(``drift_ppm`` is the clock's rate error at the segment's start, ``drift_rate_ppm_per_day``
how fast that rate changes). The segment of a time is found from the receiver's time; the
first segment also covers earlier times and the last one later times. The time keeper's
correction is zero: the common time base is its clock. Fitted corrections are continuous,
with a continuous rate, across segment boundaries (:func:`hmmtrack.sync.fit_clocks`).

The clock file is JSON, schema ``hmmtrack.receiver_clocks`` version 1 (see
``docs/interfaces.md``); :func:`read_clocks` refuses other schemas and versions, and unknown
or missing keys, naming the file and the field.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack import __version__

SCHEMA = "hmmtrack.receiver_clocks"
VERSION = 1
PPM = 1e-6
DAY = 86400.0

#: the per-receiver entries of the clock file, beside the per-segment coefficients
_RECEIVER_KEYS = (
    "receiver",
    "sync_tag",
    "fixed",
    "x",
    "y",
    "z",
    "x_file",
    "y_file",
    "z_file",
    "offset_s",
    "drift_ppm",
    "drift_rate_ppm_per_day",
    "residual_sd_ms",
    "detections",
    "rejected",
)
_TOP_KEYS = (
    "schema",
    "version",
    "package_version",
    "model",
    "time_keeper",
    "segments",
    "sound_speed",
    "receivers",
    "pings",
    "echoes_dropped",
    "outliers_rejected",
    "settings",
)
_MODEL_TEXT = (
    "common = t - (offset_s + drift_ppm*1e-6*u + 0.5*drift_rate_ppm_per_day*1e-6*u**2/86400), "
    "t the receiver's time (UTC epoch s), u = t - start of t's segment (s); the first segment "
    "also covers earlier times, the last one later times"
)


@dataclass(frozen=True)
class ReceiverClocks:
    """Every receiver's clock relative to a time keeper, as fitted from sync tags.

    Parameters
    ----------
    time_keeper : str
        The receiver whose clock is the common time base.
    receivers : tuple of str
        Receiver names, shape (R,).
    segment_starts, segment_ends : (K,) float arrays
        Segment bounds (UTC epoch s, time keeper's clock).
    coefficients : (R, K, 3) float array
        Per receiver and segment: ``offset_s`` (s), ``drift_ppm``, ``drift_rate_ppm_per_day``.
    sound_speed : (K,) float array
        Sound speed (m/s) per segment.
    sound_speed_method : str
        ``"estimated"``, ``"fixed"`` or ``"mackenzie"`` (from temperature and salinity).
    positions : (R, 3) float array
        Receiver positions x, y, z (m) as used by the fit (refined where not fixed).
    file_positions : (R, 3) float array
        Positions as given in the receivers file.
    fixed : (R,) bool array
        Whether a position was held at the file's value.
    sync_tags : tuple of str or None
        Sync tag moored at each receiver (None for none).
    residual_sd_ms : (R,) float array
        Standard deviation (ms) of each receiver's kept sync residuals.
    detections, rejected : (R,) int arrays
        Sync detections each receiver contributed, and of those the ones rejected as
        outliers (multipath).
    pings : int
        Sync-tag emissions used (heard by at least two receivers).
    echoes_dropped : int
        Later detections of one emission at one receiver, dropped before fitting.
    settings : dict
        The fit's settings, for the record.
    """

    time_keeper: str
    receivers: tuple[str, ...]
    segment_starts: np.ndarray
    segment_ends: np.ndarray
    coefficients: np.ndarray
    sound_speed: np.ndarray
    sound_speed_method: str
    positions: np.ndarray
    file_positions: np.ndarray
    fixed: np.ndarray
    sync_tags: tuple[str | None, ...]
    residual_sd_ms: np.ndarray
    detections: np.ndarray
    rejected: np.ndarray
    pings: int = 0
    echoes_dropped: int = 0
    settings: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n, k = len(self.receivers), len(self.segment_starts)
        if self.time_keeper not in self.receivers:
            raise ValueError(f"ReceiverClocks: time keeper {self.time_keeper!r} not a receiver")
        if self.coefficients.shape != (n, k, 3):
            raise ValueError(
                f"ReceiverClocks: coefficients have shape {self.coefficients.shape}; "
                f"expected {(n, k, 3)}"
            )
        if k < 1 or np.any(np.diff(self.segment_starts) <= 0):
            raise ValueError("ReceiverClocks: segment starts must increase")

    def correction(self, receiver: str, time) -> np.ndarray:
        """Receiver time minus common time (s) at receiver times ``time`` (s), any shape."""
        try:
            row = self.receivers.index(receiver)
        except ValueError:
            raise ValueError(
                f"no clock for receiver {receiver!r}; the clock file has {list(self.receivers)}"
            ) from None
        time = np.asarray(time, dtype=float)
        segment = np.clip(
            np.searchsorted(self.segment_starts, time, side="right") - 1,
            0,
            len(self.segment_starts) - 1,
        )
        offset, drift, rate = np.moveaxis(self.coefficients[row, segment], -1, 0)
        u = time - self.segment_starts[segment]
        return offset + drift * PPM * u + 0.5 * rate * PPM * u**2 / DAY

    def to_common(self, receiver: str, time) -> np.ndarray:
        """Common times (s) of receiver times ``time`` (s), any shape."""
        time = np.asarray(time, dtype=float)
        return time - self.correction(receiver, time)

    # -- file ---------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """The JSON document of these clocks (plain Python types)."""
        receivers = []
        for i, name in enumerate(self.receivers):
            x, y, z = (float(v) for v in self.positions[i])
            fx, fy, fz = (float(v) for v in self.file_positions[i])
            receivers.append(
                {
                    "receiver": name,
                    "sync_tag": self.sync_tags[i],
                    "fixed": bool(self.fixed[i]),
                    "x": x,
                    "y": y,
                    "z": z,
                    "x_file": fx,
                    "y_file": fy,
                    "z_file": fz,
                    "offset_s": self.coefficients[i, :, 0].tolist(),
                    "drift_ppm": self.coefficients[i, :, 1].tolist(),
                    "drift_rate_ppm_per_day": self.coefficients[i, :, 2].tolist(),
                    "residual_sd_ms": _float_or_none(self.residual_sd_ms[i]),
                    "detections": int(self.detections[i]),
                    "rejected": int(self.rejected[i]),
                }
            )
        return {
            "schema": SCHEMA,
            "version": VERSION,
            "package_version": __version__,
            "model": _MODEL_TEXT,
            "time_keeper": self.time_keeper,
            "segments": [
                {"start": float(s), "end": float(e)}
                for s, e in zip(self.segment_starts, self.segment_ends, strict=True)
            ],
            "sound_speed": {
                "method": self.sound_speed_method,
                "m_per_s": self.sound_speed.tolist(),
            },
            "receivers": receivers,
            "pings": int(self.pings),
            "echoes_dropped": int(self.echoes_dropped),
            "outliers_rejected": int(self.rejected.sum()),
            "settings": dict(self.settings),
        }

    @classmethod
    def from_dict(cls, document, source: str = "clocks") -> ReceiverClocks:
        """Validate a clock document (see :meth:`to_dict`) and build the clocks."""
        reader = _Reader(document, source)
        reader.keys(document, "", _TOP_KEYS)
        schema = reader.get(document, "schema", str)
        if schema != SCHEMA:
            reader.fail("schema", f"is {schema!r}; expected {SCHEMA!r}")
        version = reader.get(document, "version", int)
        if version != VERSION:
            reader.fail("version", f"is {version}; this hmmtrack reads version {VERSION} only")
        segments = reader.get(document, "segments", list)
        for k, segment in enumerate(segments):
            reader.keys(segment, f"segments[{k}]", ("start", "end"))
        starts = np.array([reader.number(s, "start") for s in segments])
        ends = np.array([reader.number(s, "end") for s in segments])
        sound = reader.get(document, "sound_speed", dict)
        reader.keys(sound, "sound_speed", ("method", "m_per_s"))
        speeds = reader.numbers(sound, "sound_speed.m_per_s", len(segments), key="m_per_s")
        entries = reader.get(document, "receivers", list)
        rows = []
        for i, entry in enumerate(entries):
            where = f"receivers[{i}]"
            reader.keys(entry, where, _RECEIVER_KEYS)
            tag = entry["sync_tag"]
            if tag is not None and not isinstance(tag, str):
                reader.fail(f"{where}.sync_tag", f"is {tag!r}; expected a string or null")
            if not isinstance(entry["fixed"], bool):
                reader.fail(f"{where}.fixed", f"is {entry['fixed']!r}; expected true or false")
            coefficients = [
                reader.numbers(entry, f"{where}.{key}", len(segments), key=key)
                for key in ("offset_s", "drift_ppm", "drift_rate_ppm_per_day")
            ]
            sd = entry["residual_sd_ms"]
            rows.append(
                {
                    "receiver": reader.get(entry, "receiver", str, where),
                    "sync_tag": tag,
                    "fixed": entry["fixed"],
                    "position": [reader.number(entry, k, where) for k in ("x", "y", "z")],
                    "file": [
                        reader.number(entry, k, where) for k in ("x_file", "y_file", "z_file")
                    ],
                    "coefficients": np.stack(coefficients, axis=-1),
                    "sd": math.nan if sd is None else reader.number(entry, "residual_sd_ms", where),
                    "detections": reader.get(entry, "detections", int, where),
                    "rejected": reader.get(entry, "rejected", int, where),
                }
            )
        try:
            return cls(
                time_keeper=reader.get(document, "time_keeper", str),
                receivers=tuple(r["receiver"] for r in rows),
                segment_starts=starts,
                segment_ends=ends,
                coefficients=np.array([r["coefficients"] for r in rows]).reshape(
                    len(rows), len(segments), 3
                ),
                sound_speed=speeds,
                sound_speed_method=reader.get(sound, "method", str, "sound_speed"),
                positions=np.array([r["position"] for r in rows]).reshape(-1, 3),
                file_positions=np.array([r["file"] for r in rows]).reshape(-1, 3),
                fixed=np.array([r["fixed"] for r in rows], dtype=bool),
                sync_tags=tuple(r["sync_tag"] for r in rows),
                residual_sd_ms=np.array([r["sd"] for r in rows]),
                detections=np.array([r["detections"] for r in rows], dtype=int),
                rejected=np.array([r["rejected"] for r in rows], dtype=int),
                pings=reader.get(document, "pings", int),
                echoes_dropped=reader.get(document, "echoes_dropped", int),
                settings=reader.get(document, "settings", dict),
            )
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from exc


def write_clocks(clocks: ReceiverClocks, path: str | Path) -> None:
    """Write a clock file (JSON, schema ``hmmtrack.receiver_clocks`` version 1)."""
    Path(path).write_text(json.dumps(clocks.to_dict(), indent=2) + "\n", encoding="utf-8")


def read_clocks(path: str | Path) -> ReceiverClocks:
    """Read and validate a clock file written by :func:`write_clocks`.

    Raises
    ------
    ValueError
        Naming the file and the field, for another schema or version, an unknown or missing
        key, or a malformed value.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a JSON file ({exc})") from exc
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a JSON file (not UTF-8 text: {exc.reason})") from exc
    return ReceiverClocks.from_dict(document, source=str(path))


def apply_clocks(detections: pd.DataFrame, clocks: ReceiverClocks) -> pd.DataFrame:
    """Detections with ``time`` moved from each receiver's clock to the common time base.

    Parameters
    ----------
    detections : DataFrame
        The detections table (``time`` in each receiver's own clock, UTC epoch s,
        ``receiver``); other columns are kept.
    clocks : ReceiverClocks
        Every receiver of ``detections`` must have a clock.

    Returns
    -------
    DataFrame
        A copy, ``time`` on the common time base (the time keeper's clock), the logged time
        kept as ``receiver_time``, sorted by the new time (stable); attrs kept, plus
        ``attrs["time_keeper"]`` and ``attrs["sound_speed"]`` (the fit's, m/s, the mean over
        its segments: what the arrival times are consistent with).
    """
    missing = sorted(set(detections["receiver"]) - set(clocks.receivers))
    if missing:
        raise ValueError(
            f"no clock for receiver(s) {missing}; the clock file has {list(clocks.receivers)} "
            "(receivers without sync-tag detections cannot be synchronised)"
        )
    out = detections.copy()
    recorded = detections["time"].to_numpy(dtype=float)
    common = recorded.copy()
    names = detections["receiver"].to_numpy()
    for name in pd.unique(names):
        rows = names == name
        common[rows] = clocks.to_common(name, recorded[rows])
    out["time"] = common
    out["receiver_time"] = recorded
    out = out.iloc[np.argsort(common, kind="stable")]
    out.attrs = dict(detections.attrs) | {
        "time_keeper": clocks.time_keeper,
        "sound_speed": float(np.mean(clocks.sound_speed)),
    }
    return out


def _float_or_none(value: float) -> float | None:
    return None if not np.isfinite(value) else float(value)


class _Reader:
    """Field access on a clock document with errors naming the source and field."""

    def __init__(self, document, source: str):
        if not isinstance(document, dict):
            raise ValueError(f"{source}: expected a JSON object at the top level")
        self.source = source

    def fail(self, name: str, message: str):
        raise ValueError(f"{self.source}: field {name!r} {message}")

    def keys(self, block, where: str, expected: tuple[str, ...]) -> None:
        if not isinstance(block, dict):
            self.fail(where, "is not a JSON object")
        unknown = sorted(set(block) - set(expected))
        if unknown:
            self.fail(where or "(top level)", f"has unknown key(s) {unknown}")
        missing = [k for k in expected if k not in block]
        if missing:
            self.fail(where or "(top level)", f"lacks key(s) {missing}")

    def get(self, block: dict, name: str, kind: type, where: str = ""):
        value = block[name]
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            self.fail(
                f"{where}.{name}" if where else name, f"is {value!r}; expected {kind.__name__}"
            )
        return value

    def number(self, block: dict, name: str, where: str = "") -> float:
        value = block[name]
        if (
            not isinstance(value, int | float)
            or isinstance(value, bool)
            or not math.isfinite(value)
        ):
            self.fail(f"{where}.{name}" if where else name, f"is {value!r}; expected a number")
        return float(value)

    def numbers(self, block: dict, name: str, length: int, key: str) -> np.ndarray:
        values = block[key]
        if (
            not isinstance(values, list)
            or len(values) != length
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
            or not all(math.isfinite(v) for v in values)
        ):
            self.fail(name, f"is {values!r}; expected {length} finite numbers (one per segment)")
        return np.array(values, dtype=float)
