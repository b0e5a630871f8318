"""The tracking configuration: the few numbers a tracking run needs beyond its data files.

:class:`TrackingConfig` holds the tag period, sound speed, known initial ranges, search
bounds, measurement model and its noise, motion model and its noise, particle count,
prediction step and depth policy. It is validated when built (whatever the source) and
can be read from a small JSON file whose keys are the field names, e.g.::

    {"period": 8.179, "r0": {"VR2W-1": 12.0, "VR2W-2": 230.0},
     "measurement_covariance": [[25.0, 0.0], [0.0, 0.25]], "n_particles": 5000}

A *preset* is a bundled JSON file of settings only (no period, ranges, bounds or times:
those describe the data) for one kind of deployment, read by name with
:func:`read_preset` (:func:`preset_names` lists them); ``two-moving-receivers`` holds the
arrival-time filter's settings for two AUVs circling the tag
(``benchmarks/bench_two_auv_plan.py``). :func:`merge_settings` layers a preset, a file
and command-line values, later ones winning; :func:`measurement_covariance_with` sets the
standard deviations of Σ_z (``hmmtrack track --sigma-range``). The arrival-time filter's
detection curve is a key too, e.g. ``"detection_curve": {"range_50": 160, "width": 40}``.

It is not for running anything: :func:`hmmtrack.tracking.pipeline.track` uses it, the
measurements build themselves from it (their ``from_config``), and
:meth:`TrackingConfig.motion_model` turns its motion settings into a motion model.
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

from hmmtrack.tracking.filter import RESAMPLE_WHEN
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.measurement.ranging import SOUND_SPEED
from hmmtrack.tracking.motion import MOTIONS, motion_model
from hmmtrack.tracking.resampling import RESAMPLERS

#: depth policies that are not a number (see :attr:`TrackingConfig.depth`)
DEPTH_POLICIES = ("none", "sensor")

#: free-text keys a configuration file may carry and that tracking ignores (the
#: ``scenario.json`` written by ``hmmtrack simulate`` has them)
DESCRIPTIVE_KEYS = ("name", "description", "files", "synthetic")

#: keys that describe one data set, which a preset may not hold
DATA_KEYS = ("period", "r0", "transmitter", "bounds", "start", "end")

#: folder of the bundled presets, one ``<name>.json`` each
PRESET_DIR = Path(__file__).resolve().parents[1] / "data" / "presets"


def _number(name: str, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return number


def _positive(name: str, value) -> float:
    number = _number(name, value)
    if number <= 0:
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
        per detecting receiver; arrival-time tracking (:mod:`hmmtrack.tracking.measurement.clocked`)
        needs none (empty mapping, the default).
    sound_speed : float
        Speed of sound (m/s); 1460 as the paper.
    transmitter : str or None
        Transmitter to track; ``None`` when the detections hold just one.
    bounds : (xmin, xmax, ymin, ymax) or None
        Search region for the initial particles, in metres of the tracking frame: the
        receivers' ``x``/``y``, or for receivers read as lon/lat the projection
        :func:`hmmtrack.io.read_receivers` chose for them (the UTM zone of their centre by
        default; ``hmmtrack track --bounds`` converts a lon/lat box into it). ``None``
        derives it: from the receivers' first positions and ``r0``
        (:func:`hmmtrack.tracking.measurement.range_rate.search_bounds`) for ``"range-rate"``, from
        ``search_radius`` for ``"arrival-time"``.
    bounds_margin : float
        ``"range-rate"``: margin (m) added around derived bounds, and the slack of
        :func:`hmmtrack.tracking.measurement.range_rate.check_bounds` for given ones.
    velocity_window : float
        Width (s) of the window over which receiver velocities are averaged from their GPS
        tracks (see :class:`hmmtrack.tracking.receivers.ReceiverTracks`); 0 takes the slope of the
        GPS segment, as noisy as the fixes.
    measurement_covariance : 2×2 nested sequence
        Σ_z of (range m, range_rate m/s): ``[[var_r, cov], [cov, var_rdot]]``; symmetric
        positive definite. Estimate it with
        :func:`hmmtrack.tracking.measurement.ranging.estimate_measurement_covariance` and
        :func:`hmmtrack.analysis.calibration.expected_measurements`, then inflate it: the filter's
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
        :func:`hmmtrack.tracking.measurement.ranging.depth_correction`).
    start, end : float, str or None
        Time window of the run: UTC epoch seconds or ISO 8601 text with a UTC offset
        (stored as seconds); ``None`` uses the first and last detection.
    resampling : str
        Resampling scheme, a name of :data:`hmmtrack.tracking.resampling.RESAMPLERS`. Default
        ``"systematic"`` (less resampling noise than the paper's ``"multinomial"``; on 10
        trials per cell of the three synthetic scenarios it lowered the HMM model's mean
        error after convergence on the shark pursuit from 77 m to 24 m and was never
        clearly worse, see :mod:`hmmtrack.tracking.pipeline`); ``"multinomial"`` with
        ``resample_when="always"`` is the paper's algorithm.
    resample_when : {"always", "ess"}
        Resample after every correction (``"always"``, the paper, and the default) or only
        when the effective sample size falls below ``ess_threshold * n_particles`` (no
        clear gain on the synthetic scenarios).
    ess_threshold : float
        Fraction in ``(0, 1]`` for ``resample_when="ess"``.
    measurement : {"range-rate", "arrival-time"}
        Measurement model, a name of :data:`hmmtrack.tracking.measurement.MEASUREMENTS`: the
        paper's ranges and range-rates from the tag period and known initial ranges
        (``"range-rate"``, the default), or arrival times scored against the tag's emission
        clock carried by each particle (``"arrival-time"``).
    motion : {"baseline", "velocity", "hmm"}
        Motion model of :meth:`motion_model` (:data:`hmmtrack.tracking.motion.MOTIONS`);
        ``"hmm"``,
        the bundled white-shark model, by default.
    sigma_speed, sigma_turn_rate : float or None
        ``motion="velocity"`` only: spreads of the speed (m/s per √s) and turn-rate (rad/s
        per √s) increments of :class:`hmmtrack.tracking.motion.VelocityMotion`; ``None`` keeps
        :data:`hmmtrack.tracking.motion.VELOCITY_SIGMA_SPEED` and ``VELOCITY_SIGMA_TURN_RATE``.
    arrival_sigma : float or None
        ``measurement="arrival-time"`` only: standard deviation (s) of a direct-path
        arrival-time residual
        (:class:`hmmtrack.tracking.measurement.arrival_time.ArrivalLikelihood`'s ``sigma``);
        ``None`` keeps that class's default.
    tempering_ess : float or None
        ``measurement="arrival-time"`` only: fraction in ``(0, 1)`` of the particles below
        which a correction is tempered (:class:`hmmtrack.tracking.tempering.Tempered`);
        ``None`` keeps the measurement's default
        (:data:`hmmtrack.tracking.measurement.clocked.TEMPERING_ESS`).
    search_radius : float or None
        ``measurement="arrival-time"`` only, without ``bounds``: the search box is the
        receivers' positions at the start widened by this many metres (about their
        detection range); ``None`` keeps
        :data:`hmmtrack.tracking.measurement.clocked.SEARCH_RADIUS`.
    detection_curve : LogisticDetection, mapping or None
        ``measurement="arrival-time"`` only: the receivers' probability of hearing a ping
        against range, so that pings a particle says should have been heard but were not
        count against it (:class:`hmmtrack.tracking.measurement.detection.LogisticDetection`,
        ``max_probability`` 1; in a file ``{"range_50": m, "width": m}``). ``None``:
        missed pings carry no information.
    mixture : bool
        Keep every mode of the posterior: resample each component of the particle cloud on
        its own (:class:`hmmtrack.tracking.mixture.Mixture`, its default settings) and
        report the components (``TrackingResult.modes``); ``False`` resamples the whole
        cloud (the paper's algorithm).
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
    measurement: str = "range-rate"
    motion: str = "hmm"
    sigma_speed: float | None = None
    sigma_turn_rate: float | None = None
    arrival_sigma: float | None = None
    tempering_ess: float | None = None
    search_radius: float | None = None
    detection_curve: LogisticDetection | None = None
    mixture: bool = False

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
        self._check_models()

    def _check_models(self) -> None:
        if self.measurement not in MEASUREMENTS:
            raise ValueError(
                f"measurement must be one of {tuple(MEASUREMENTS)}, got {self.measurement!r}"
            )
        if self.motion not in MOTIONS:
            raise ValueError(f"motion must be one of {tuple(MOTIONS)}, got {self.motion!r}")
        set_ = object.__setattr__
        for name in ("sigma_speed", "sigma_turn_rate"):
            value = getattr(self, name)
            if value is None:
                continue
            if self.motion != "velocity":
                raise ValueError(f"{name} is a setting of motion 'velocity', not {self.motion!r}")
            number = _number(name, value)
            if number < 0:
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
            set_(self, name, number)
        for name in ("arrival_sigma", "tempering_ess", "search_radius"):
            value = getattr(self, name)
            if value is None:
                continue
            if self.measurement != "arrival-time":
                raise ValueError(
                    f"{name} is a setting of measurement 'arrival-time', not {self.measurement!r}"
                )
            set_(self, name, _positive(name, value))
        if self.tempering_ess is not None and self.tempering_ess > 1:
            raise ValueError(f"tempering_ess must lie in (0, 1], got {self.tempering_ess!r}")
        if self.detection_curve is not None:
            if self.measurement != "arrival-time":
                raise ValueError(
                    "detection_curve is a setting of measurement 'arrival-time' (missed pings "
                    f"count in its filter only), not {self.measurement!r}"
                )
            set_(self, "detection_curve", _detection_curve(self.detection_curve))

    def motion_model(self, model=None, variant: str = "time_consistent", resting="default"):
        """The motion model these settings name, with their noise.

        Parameters
        ----------
        model, variant, resting
            For ``motion="hmm"`` only, see :func:`hmmtrack.tracking.motion.motion_model`
            (``resting=None``: no resting state added to the movement HMM).

        Returns
        -------
        BaselineMotion, VelocityMotion or HMMMotion
            :func:`hmmtrack.tracking.motion.motion_model`'s, with :attr:`sigma_speed` and
            :attr:`sigma_turn_rate` where given.
        """
        motion = motion_model(self.motion, model, variant=variant, resting=resting)
        noise = {
            name: getattr(self, name)
            for name in ("sigma_speed", "sigma_turn_rate")
            if getattr(self, name) is not None
        }
        return dataclasses.replace(motion, **noise) if noise else motion

    def override(self, **changes) -> TrackingConfig:
        """A validated copy with ``changes`` applied; ``None`` values mean "not given"."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_dict(self) -> dict:
        """Plain JSON-ready dictionary; :meth:`from_dict` reads it back."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["r0"] = dict(self.r0)
        out["bounds"] = None if self.bounds is None else list(self.bounds)
        out["measurement_covariance"] = [list(row) for row in self.measurement_covariance]
        if self.detection_curve is not None:
            curve = self.detection_curve
            out["detection_curve"] = {"range_50": curve.range_50, "width": curve.width}
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
        return cls.from_dict(merge_settings(read_settings(path), overrides), source=str(path))


def read_settings(path: str | Path) -> dict:
    """The JSON object of settings in ``path`` (keys unchecked: :meth:`TrackingConfig.from_dict`
    checks them)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object of settings")
    return data


def merge_settings(*layers: Mapping) -> dict:
    """Settings of ``layers`` (e.g. preset, file, command line), later layers winning.

    ``None`` values mean "not given" and are skipped; ``r0`` mappings are merged receiver
    by receiver.
    """
    merged: dict = {}
    for layer in layers:
        for key, value in layer.items():
            if value is None:
                continue
            if key == "r0" and isinstance(merged.get("r0"), Mapping) and isinstance(value, Mapping):
                value = dict(merged["r0"]) | dict(value)
            merged[key] = value
    return merged


def preset_names() -> list[str]:
    """Names of the bundled presets (:data:`PRESET_DIR`), sorted."""
    return sorted(path.stem for path in PRESET_DIR.glob("*.json"))


def read_preset(name: str) -> dict:
    """The settings of the bundled preset ``name``, without its descriptive keys.

    Parameters
    ----------
    name : str
        One of :func:`preset_names`.

    Returns
    -------
    dict
        Keys of :class:`TrackingConfig` other than :data:`DATA_KEYS`: combine them with
        the data's period (and ranges, bounds, times) in :meth:`TrackingConfig.from_dict`.

    Raises
    ------
    ValueError
        For an unknown name (naming the available presets), or a preset file with unknown
        keys or keys that describe data.
    """
    names = preset_names()
    if name not in names:
        raise ValueError(f"unknown preset {name!r}; available presets: {', '.join(names)}")
    path = PRESET_DIR / f"{name}.json"
    data = {k: v for k, v in read_settings(path).items() if k not in DESCRIPTIVE_KEYS}
    known = {f.name for f in dataclasses.fields(TrackingConfig)} - set(DATA_KEYS)
    wrong = sorted(set(data) - known)
    if wrong:
        raise ValueError(
            f"{path}: key(s) {wrong} are not settings a preset may hold; "
            f"allowed keys are {sorted(known)}"
        )
    return data


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


def measurement_covariance_with(
    covariance, sigma_range: float | None = None, sigma_range_rate: float | None = None
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Σ_z with new standard deviations of range and/or range-rate, correlation kept.

    Parameters
    ----------
    covariance : 2×2 nested sequence
        Σ_z of (range m, range-rate m/s), as :attr:`TrackingConfig.measurement_covariance`.
    sigma_range : float, optional
        New standard deviation of the range (m); ``None`` keeps Σ_z's.
    sigma_range_rate : float, optional
        New standard deviation of the range-rate (m/s); ``None`` keeps Σ_z's.

    Returns
    -------
    ((var_r, cov), (cov, var_rdot))
        Diagonal set from the standard deviations; the off-diagonal term rescaled so that
        the correlation of range and range-rate stays that of ``covariance`` (0 for the
        paper's diagonal Σ_z).
    """
    (var_r, cov), (_, var_rdot) = _covariance(covariance)
    sigmas = [math.sqrt(var_r), math.sqrt(var_rdot)]
    correlation = cov / (sigmas[0] * sigmas[1])
    for i, (name, value) in enumerate(
        (("sigma_range", sigma_range), ("sigma_range_rate", sigma_range_rate))
    ):
        if value is not None:
            sigmas[i] = _positive(name, value)
    cov = correlation * sigmas[0] * sigmas[1]
    return ((sigmas[0] ** 2, cov), (cov, sigmas[1] ** 2))


def _detection_curve(value) -> LogisticDetection:
    if isinstance(value, LogisticDetection):
        curve = value
    else:
        keys = ("range_50", "width")
        if not isinstance(value, Mapping) or set(value) != set(keys):
            raise ValueError(
                'detection_curve must be {"range_50": metres, "width": metres} (the logistic '
                f"curve of hmmtrack.tracking.measurement.detection.LogisticDetection), got "
                f"{value!r}"
            )
        curve = LogisticDetection(*(_number(f"detection_curve {k}", value[k]) for k in keys))
    curve.require_unit_maximum("detection_curve")
    return curve


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
