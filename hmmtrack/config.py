"""The tracking configuration: the few numbers a tracking run needs beyond its data files.

:class:`TrackingConfig` holds the tag period, sound speed, known initial ranges, search
bounds, measurement covariance, particle count, prediction step and depth policy. It is
validated when built (whatever the source) and can be read from a small JSON file whose
keys are the field names, e.g.::

    {"period": 8.179, "r0": {"VR2W-1": 12.0, "VR2W-2": 230.0},
     "measurement_covariance": [[25.0, 0.0], [0.0, 0.25]], "n_particles": 5000}

Command-line arguments override file values (:meth:`TrackingConfig.override`).

It is not for running anything: :mod:`hmmtrack.tracking` uses it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hmmtrack.filter import RESAMPLE_WHEN
from hmmtrack.ranging import SOUND_SPEED
from hmmtrack.resampling import RESAMPLERS

#: depth policies that are not a number (see :attr:`TrackingConfig.depth`)
DEPTH_POLICIES = ("none", "sensor")

#: free-text keys a configuration file may carry and that tracking ignores (the
#: ``scenario.json`` written by ``hmmtrack simulate`` has them)
DESCRIPTIVE_KEYS = ("name", "description", "files", "synthetic")


def _positive(name: str, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(number) or number <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return number


@dataclass(frozen=True)
class TrackingConfig:
    """Settings of one tracking run.

    Parameters
    ----------
    period : float
        Transmitter period ``T`` (s), e.g. 8.179.
    r0 : mapping of str to float
        Known range (m, ≥ 0) between the tag and each receiver at that receiver's first
        detection, keyed by receiver name. The paper's (range, range-rate) tracking needs one
        per detecting receiver; arrival-time tracking (:mod:`hmmtrack.clock_tracking`) needs
        none (empty mapping, the default).
    sound_speed : float
        Speed of sound (m/s); 1460 as the paper.
    transmitter : str or None
        Transmitter to track; ``None`` when the detections hold just one.
    bounds : (xmin, xmax, ymin, ymax) or None
        Search region for the initial particles (m, receivers' frame). ``None`` derives it
        from the receivers' first positions and ``r0`` (see
        :func:`hmmtrack.tracking.search_bounds`).
    bounds_margin : float
        Margin added around derived bounds (m).
    velocity_window : float
        Width (s) of the window over which receiver velocities are averaged from their GPS
        tracks (see :class:`hmmtrack.receivers.ReceiverTracks`); 0 takes the slope of the
        GPS segment, as noisy as the fixes.
    measurement_covariance : 2×2 nested sequence
        Σ_z of (range m, range_rate m/s): ``[[var_r, cov], [cov, var_rdot]]``; symmetric
        positive definite. Estimate it with
        :func:`hmmtrack.ranging.estimate_measurement_covariance` and
        :func:`hmmtrack.tracking.expected_measurements`, then inflate it: the filter's
        likelihood must also absorb the particles' spread. The default (5 m, 0.5 m/s; the
        paper gives no value) is 3-5 times the error standard deviations measured on the
        synthetic scenarios (1.1-1.5 m, 0.10-0.18 m/s); Σ_z set to (2 m, 0.2 m/s) made the
        stationary-tag runs worse (mean error after convergence 14.8 m against 5.8 m).
    n_particles : int
        Number of particles.
    prediction_step : float
        Time between predictions and between estimates (s); 1 s as the paper.
    depth : "none", "sensor" or float
        Depth correction of the ranges: ``"none"`` (2-D, the paper), ``"sensor"`` (the
        detections' ``depth`` column, a tag depth sensor) or an assumed constant depth (m).
    shallower : {"raise", "clip"}
        What a depth correction does with a range shorter than the depth (see
        :func:`hmmtrack.ranging.depth_correction`).
    start, end : float, str or None
        Time window of the run: UTC epoch seconds or ISO 8601 text with a UTC offset
        (stored as seconds); ``None`` uses the first and last detection.
    resampling : str
        Resampling scheme, a name of :data:`hmmtrack.resampling.RESAMPLERS`. Default
        ``"systematic"`` (less resampling noise than the paper's ``"multinomial"``; on 10
        trials per cell of the three synthetic scenarios it lowered the HMM model's mean
        error after convergence on the shark pursuit from 77 m to 24 m and was never
        clearly worse, see :mod:`hmmtrack.tracking`); ``"multinomial"`` with
        ``resample_when="always"`` is the paper's algorithm.
    resample_when : {"always", "ess"}
        Resample after every correction (``"always"``, the paper, and the default) or only
        when the effective sample size falls below ``ess_threshold * n_particles`` (no
        clear gain on the synthetic scenarios).
    ess_threshold : float
        Fraction in ``(0, 1]`` for ``resample_when="ess"``.
    """

    period: float
    r0: Mapping[str, float] = dataclasses.field(default_factory=dict)
    sound_speed: float = SOUND_SPEED
    transmitter: str | None = None
    bounds: tuple[float, float, float, float] | None = None
    bounds_margin: float = 100.0
    velocity_window: float = 20.0
    measurement_covariance: tuple[tuple[float, float], tuple[float, float]] = (
        (25.0, 0.0),
        (0.0, 0.25),
    )
    n_particles: int = 5000
    prediction_step: float = 1.0
    depth: str | float = "none"
    shallower: str = "raise"
    start: float | None = None
    end: float | None = None
    resampling: str = "systematic"
    resample_when: str = "always"
    ess_threshold: float = 0.5

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "period", _positive("period", self.period))
        set_(self, "sound_speed", _positive("sound_speed", self.sound_speed))
        set_(self, "prediction_step", _positive("prediction_step", self.prediction_step))
        if not isinstance(self.r0, Mapping):
            raise ValueError(f"r0 must map receiver names to ranges (m), got {self.r0!r}")
        r0 = {}
        for receiver, value in self.r0.items():
            try:
                metres = float(value)
            except (TypeError, ValueError):
                metres = math.nan
            if not math.isfinite(metres) or metres < 0:
                raise ValueError(
                    f"r0 of receiver {receiver!r} must be a non-negative range in metres, "
                    f"got {value!r}"
                )
            r0[str(receiver)] = metres
        set_(self, "r0", r0)
        if self.transmitter is not None:
            set_(self, "transmitter", str(self.transmitter))
        if self.bounds is not None:
            try:
                bounds = tuple(float(b) for b in self.bounds)
            except (TypeError, ValueError):
                bounds = ()
            if (
                len(bounds) != 4
                or not all(map(math.isfinite, bounds))
                or not (bounds[0] < bounds[1] and bounds[2] < bounds[3])
            ):
                raise ValueError(
                    f"bounds must be (xmin, xmax, ymin, ymax) with xmin < xmax and ymin < ymax, "
                    f"got {self.bounds!r}"
                )
            set_(self, "bounds", bounds)
        for name in ("bounds_margin", "velocity_window"):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
            set_(self, name, value)
        set_(self, "measurement_covariance", _covariance(self.measurement_covariance))
        n = self.n_particles
        if isinstance(n, bool) or not isinstance(n, numbers.Real) or n != int(n) or n < 1:
            raise ValueError(f"n_particles must be a positive integer, got {n!r}")
        set_(self, "n_particles", int(n))
        set_(self, "depth", _depth(self.depth))
        if self.shallower not in ("raise", "clip"):
            raise ValueError(f"shallower must be 'raise' or 'clip', got {self.shallower!r}")
        for name in ("start", "end"):
            set_(self, name, _instant(name, getattr(self, name)))
        if self.start is not None and self.end is not None and not self.start < self.end:
            raise ValueError(f"start ({self.start}) must be before end ({self.end})")
        if self.resampling not in RESAMPLERS:
            raise ValueError(
                f"resampling must be one of {sorted(RESAMPLERS)}, got {self.resampling!r}"
            )
        if self.resample_when not in RESAMPLE_WHEN:
            raise ValueError(
                f"resample_when must be one of {RESAMPLE_WHEN}, got {self.resample_when!r}"
            )
        threshold = _positive("ess_threshold", self.ess_threshold)
        if threshold > 1:
            raise ValueError(f"ess_threshold must lie in (0, 1], got {self.ess_threshold!r}")
        set_(self, "ess_threshold", threshold)

    def override(self, **changes) -> TrackingConfig:
        """A validated copy with ``changes`` applied; ``None`` values mean "not given"."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_dict(self) -> dict:
        """Plain JSON-ready dictionary; :meth:`from_dict` reads it back."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["r0"] = dict(self.r0)
        out["bounds"] = None if self.bounds is None else list(self.bounds)
        out["measurement_covariance"] = [list(row) for row in self.measurement_covariance]
        return out

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "configuration") -> TrackingConfig:
        """Build from a dictionary, naming ``source`` and the key in any error."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a JSON object of settings, got {type(data)}")
        known = [f.name for f in dataclasses.fields(cls)]
        data = {k: v for k, v in data.items() if k not in DESCRIPTIVE_KEYS}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ValueError(f"{source}: unknown key(s) {unknown}; known keys are {known}")
        missing = [k for k in ("period",) if k not in data]
        if missing:
            raise ValueError(f"{source}: missing required key(s) {missing}")
        try:
            return cls(**data)
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None

    @classmethod
    def from_json(cls, path: str | Path, **overrides) -> TrackingConfig:
        """Read a JSON file; ``overrides`` (if not ``None``) replace or add keys.

        An ``r0`` override is merged receiver by receiver into the file's ``r0``.
        """
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not valid JSON ({exc})") from None
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a JSON object of settings")
        overrides = {k: v for k, v in overrides.items() if v is not None}
        if isinstance(data.get("r0"), dict) and "r0" in overrides:
            overrides["r0"] = data["r0"] | dict(overrides["r0"])
        data.update(overrides)
        return cls.from_dict(data, source=str(path))


def _covariance(value) -> tuple[tuple[float, float], tuple[float, float]]:
    message = (
        "measurement_covariance must be a symmetric positive definite 2x2 matrix "
        f"[[var_r, cov], [cov, var_rdot]], got {value!r}"
    )
    try:
        rows = tuple(tuple(float(v) for v in row) for row in value)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    if len(rows) != 2 or any(len(row) != 2 for row in rows):
        raise ValueError(message)
    (a, b), (c, d) = rows
    if not all(map(math.isfinite, (a, b, c, d))) or b != c or a <= 0 or a * d - b * c <= 0:
        raise ValueError(message)
    return rows


def _instant(name: str, value) -> float | None:
    if value is None:
        return None
    if isinstance(value, str):
        try:
            stamp = pd.Timestamp(value)
        except ValueError:
            stamp = None
        if stamp is None or stamp.tzinfo is None:
            raise ValueError(
                f"{name} must be UTC epoch seconds or ISO 8601 text with a UTC offset "
                f"(e.g. 2022-06-08T17:00:00Z), got {value!r}"
            )
        return stamp.as_unit("ns").value / 1e9
    seconds = float(value)
    if not math.isfinite(seconds):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return seconds


def _depth(value) -> str | float:
    if isinstance(value, str):
        if value in DEPTH_POLICIES:
            return value
        try:
            value = float(value)
        except ValueError:
            raise ValueError(
                f"depth must be one of {DEPTH_POLICIES} or a depth in metres, got {value!r}"
            ) from None
    if value is None:
        return "none"
    depth = float(value)
    if not math.isfinite(depth) or depth < 0:
        raise ValueError(f"depth must be a non-negative number of metres, got {value!r}")
    return depth
