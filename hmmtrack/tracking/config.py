"""The tracking configuration: one run's settings, a section per component.

:class:`TrackingConfig` composes the settings each component declares beside itself: the
``measurement`` section (the settings class of the measurement its ``name`` picks from
:data:`hmmtrack.tracking.measurement.MEASUREMENTS`, e.g.
:class:`~hmmtrack.tracking.measurement.range_rate.RangeRateSettings`), the ``motion``
section (:data:`hmmtrack.tracking.motion.settings.MOTION_SETTINGS`) and the ``filter``
section (:class:`hmmtrack.tracking.filter.FilterSettings`), plus the keys of the run itself:
the transmitter, the search box, the time window and the smoothing lag. Each section checks
its own keys. A configuration file is the same shape in JSON, e.g.::

    {"transmitter": "A69-1602-15266", "start": "2022-06-08T17:00:00Z",
     "measurement": {"name": "range-rate", "period": 8.179,
                     "r0": {"VR2W-1": 12.0, "VR2W-2": 230.0}, "sigma_range": 3.0},
     "motion": {"name": "hmm", "model": "shark.json"},
     "filter": {"n_particles": 5000},
     "smoothing_lag": 60}

where a section may leave out any key with a default (``name`` too: ``"range-rate"`` and
``"hmm"``; the ``filter`` section may name a filter of :data:`hmmtrack.tracking.filter.FILTERS`,
``"paper"`` or ``"mode-keeping"``, whose switches its own keys then override, else it runs
:data:`~hmmtrack.tracking.filter.DEFAULT_FILTER`), a relative ``model`` path (and
``clocks``, a clock file of ``hmmtrack sync``) is relative to the file, and an unknown key
is an error that names the file, the section and the valid keys. A motion setting left
unset (``None``, "the measurement's") takes the value the measurement gives that motion
model in :data:`MEASUREMENT_MOTIONS` when the run builds its motion model
(:meth:`TrackingConfig.motion_model`): under ``range-rate-gps`` the HMM's resting tag holds
still and its held speeds take a log random walk, and the velocity model takes a smaller
speed walk with speed jumps and a still regime; a value given in the section wins.

A *preset* is a bundled file of settings only, without the keys that describe one data set
(period, ``r0``, transmitter, bounds, start, end), for one kind of deployment; read by name
with :func:`read_preset` (:func:`preset_names` lists them). :func:`merge_settings` layers
presets, files and command-line values, later ones winning (``hmmtrack track``: preset <
``--config`` file < options).

It is not for running anything: :func:`hmmtrack.tracking.pipeline.track` reads it, and each
section builds its component.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hmmtrack.tracking.filter import FILTERS, FilterSettings
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.motion.registry import (
    HMM_GPS_SPEED_DIFFUSION,
    HMM_STILL_RESTING,
    VELOCITY_GPS,
)
from hmmtrack.tracking.motion.settings import MOTION_SETTINGS, HMMSettings
from hmmtrack.tracking.settings import (
    Settings,
    instant,
    non_negative_integer,
    setting,
    text,
)

__all__ = [
    "DESCRIPTIVE_KEYS",
    "MEASUREMENT_FILTERS",
    "MEASUREMENT_MOTIONS",
    "PRESET_DIR",
    "SECTIONS",
    "TrackingConfig",
    "measurement_motion",
    "merge_settings",
    "nest",
    "preset_names",
    "read_preset",
    "read_settings",
    "section_classes",
    "section_default",
]

#: free-text keys a configuration file may carry and that tracking ignores (the
#: ``scenario.json`` written by ``hmmtrack simulate`` has them)
DESCRIPTIVE_KEYS = ("name", "description", "files", "synthetic")

#: folder of the bundled presets, one ``<name>.json`` each
PRESET_DIR = Path(__file__).resolve().parents[1] / "data" / "presets"

#: the sections of a configuration, with the name a section without ``name`` takes
SECTIONS = {"measurement": "range-rate", "motion": "hmm", "filter": None}
#: the named filter (:data:`~hmmtrack.tracking.filter.FILTERS`) a configuration that names
#: none runs with these measurements instead of
#: :data:`~hmmtrack.tracking.filter.DEFAULT_FILTER`: on YAPS's array, which hears each ping
#: at many receivers, the mode-keeping filter kept one component throughout and its smoothed
#: median was 0.03-0.09 m higher (reports/decisions.md, "The library's default filter"); the
#: ``"acquired"`` filter (the first fixes' likelihood) finds a tag on three moorings only
#: with the tempered moves' acceptance, which costs the dense simulated array
#: (reports/decisions.md, "Finding a random-interval tag on three moorings")
MEASUREMENT_FILTERS = {"ping": "paper"}
#: the motion settings a measurement runs each motion model with where the ``motion``
#: section leaves them unset (``None``): {measurement: {motion model: {key: value}}}. The
#: ``range-rate-gps`` measurement parts a still cloud's resampled copies itself (its
#: translation move), so the HMM's resting tag holds still
#: (:data:`~hmmtrack.tracking.motion.HMM_STILL_RESTING`); its regions are narrow enough to
#: show the few distinct held speeds that resampling leaves, so the swimming states' speed
#: takes a log random walk (:data:`~hmmtrack.tracking.motion.HMM_GPS_SPEED_DIFFUSION`)
#: (reports/decisions.md, "A resting tag that holds still" and "The HMM's held speed as a
#: log-speed random walk"). The velocity model takes a smaller speed walk with speed jumps
#: and a still regime (:data:`~hmmtrack.tracking.motion.VELOCITY_GPS`; its ``sigma_speed``,
#: ``jump_rate``, ``jump_sd``, ``still_rate`` and ``still_duration`` may be set here,
#: :class:`~hmmtrack.tracking.motion.settings.VelocitySettings`): its regions were too wide
#: on the swimmer and along the AUV's line of sight on the still tag (reports/decisions.md,
#: "A sticky still regime for the velocity model")
MEASUREMENT_MOTIONS = {
    "range-rate-gps": {
        "hmm": {
            "resting_drift": HMM_STILL_RESTING.drift_speed,
            "speed_diffusion": HMM_GPS_SPEED_DIFFUSION,
        },
        "velocity": VELOCITY_GPS,
    },
}


def measurement_motion(motion: Settings, measurement: str):
    """The motion model that the ``motion`` section's settings build under the measurement
    named ``measurement``: each setting the section leaves unset (``None``) and
    :data:`MEASUREMENT_MOTIONS` gives for that measurement and motion model takes that
    value; a setting given explicitly wins.

    Parameters
    ----------
    motion : Settings
        A motion section (:data:`~hmmtrack.tracking.motion.settings.MOTION_SETTINGS`).
    measurement : str
        A measurement's name (:data:`~hmmtrack.tracking.measurement.MEASUREMENTS`).

    Returns
    -------
    MotionModel
    """
    own = MEASUREMENT_MOTIONS.get(measurement, {}).get(motion.name, {})
    unset = {key: value for key, value in own.items() if getattr(motion, key) is None}
    return dataclasses.replace(motion, **unset).build()


def section_classes(section: str) -> dict[str | None, type]:
    """The settings classes of ``section`` by component name (the ``filter`` section has
    one class, :class:`~hmmtrack.tracking.filter.FilterSettings`, under ``None`` and under
    each of the named filters of :data:`~hmmtrack.tracking.filter.FILTERS`)."""
    if section == "measurement":
        return {name: cls.settings for name, cls in MEASUREMENTS.items()}
    if section == "motion":
        return dict(MOTION_SETTINGS)
    return {None: FilterSettings} | dict.fromkeys(FILTERS, FilterSettings)


def _bounds(name: str, value) -> tuple[float, float, float, float]:
    try:
        bounds = tuple(float(b) for b in value)
    except (TypeError, ValueError):
        bounds = ()
    if (
        len(bounds) != 4
        or not all(map(math.isfinite, bounds))
        or not (bounds[0] < bounds[1] and bounds[2] < bounds[3])
    ):
        raise ValueError(
            f"{name} must be (xmin, xmax, ymin, ymax) with xmin < xmax and ymin < ymax, "
            f"got {value!r}"
        )
    return bounds


@dataclass(frozen=True)
class TrackingConfig(Settings):
    """Settings of one tracking run.

    Parameters
    ----------
    measurement : Settings
        The measurement's settings (a ``settings`` class of
        :data:`~hmmtrack.tracking.measurement.MEASUREMENTS`), which name it.
    motion : Settings
        The motion model's settings (:data:`~hmmtrack.tracking.motion.settings.MOTION_SETTINGS`);
        the bundled white-shark HMM by default, or the measurement's own
        (:func:`section_default`).
    filter : FilterSettings
        Particles, resampling, prediction step and correction policy, and the switches of
        the mode-keeping filter (``TrackingConfig.from_keys(filter="paper", ...)`` names the
        paper's filter whatever the default).
    transmitter : str or None
        Transmitter to track; ``None`` when the detections hold just one.
    bounds : (xmin, xmax, ymin, ymax) or None
        Search box of the initial particles, in metres of the tracking frame (the receivers'
        ``x``/``y``, or the projection :func:`hmmtrack.io.read_receivers` chose for lon/lat
        receivers); ``None``: derived by the measurement (``start_box``).
    start, end : float, str or None
        Time window of the run: UTC epoch seconds or ISO 8601 text with a UTC offset
        (stored as seconds); ``None``: the first and last detection.
    clocks : str or None
        Clock file (:func:`hmmtrack.sync.write_clocks`; a relative path in a configuration
        file is relative to that file): the tracked transmitter's detections are moved to
        the common time base (:func:`hmmtrack.sync.apply_clocks`) before the measurement
        builds its observations. ``None``: the logged times are taken as common.
    smoothing_lag : int or None
        Steps of a fixed-lag smoother (:class:`hmmtrack.tracking.smoothing.Smoothed`; s at the
        default 1 s prediction step), whose estimates a run then also returns; ``None``: the
        measurement's ``default_smoothing_lag`` (60 for the ping measurement, none for the
        others); 0: no smoothing.
    """

    measurement: Settings
    motion: Settings = dataclasses.field(default_factory=HMMSettings)
    filter: FilterSettings = dataclasses.field(default_factory=FilterSettings)
    transmitter: str | None = setting(
        None,
        help="transmitter to track (full id or ID part) when the log holds several",
        check=text,
        data=True,
        default_text="the only one in the log",
    )
    bounds: tuple[float, float, float, float] | None = setting(
        None,
        help=(
            "search box of the initial particles, in the frame of the receivers file: metres "
            "for x/y receivers; for lon/lat receivers LON_MIN LON_MAX LAT_MIN LAT_MAX in "
            "degrees, converted with the receivers' projection (the smallest x/y box holding "
            "it; a --config file's bounds are metres of that projection)"
        ),
        check=_bounds,
        parse=float,
        nargs=4,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
        data=True,
        default_text=(
            "range-rate, the receivers' first positions widened by r0 + bounds margin; "
            "arrival-time, the receivers widened by the search radius"
        ),
    )
    start: float | None = setting(
        None,
        help="start of the run (ISO 8601 UTC or epoch seconds)",
        check=instant,
        data=True,
        default_text="the first detection",
    )
    end: float | None = setting(
        None,
        help="end of the run (ISO 8601 UTC or epoch seconds)",
        check=instant,
        data=True,
        default_text="the last detection",
    )
    clocks: str | None = setting(
        None,
        help=(
            "clock file of hmmtrack sync: each receiver's logged times are moved to the "
            "common time base before any measurement model sees them"
        ),
        check=text,
        metavar="PATH",
        data=True,
        default_text="the logged times are on one time base",
    )
    smoothing_lag: int | None = setting(
        None,
        help=(
            "write fixed-lag smoothed estimates instead of the filter's, with this lag "
            "(prediction steps, s); 0 (or --no-smooth): the filter's"
        ),
        check=non_negative_integer,
        option="smooth",
        parse=int,
        metavar="LAG",
        default_text="60 for the ping measurement, else 0",
    )

    def validate(self) -> None:
        for section in SECTIONS:
            value = getattr(self, section)
            if type(value) not in section_classes(section).values():
                raise ValueError(
                    f"{section} must be settings of one of {list(section_classes(section))}, "
                    f"got {value!r}"
                )
        if self.start is not None and self.end is not None and not self.start < self.end:
            raise ValueError(f"start ({self.start}) must be before end ({self.end})")

    def motion_model(self):
        """The run's motion model: the ``motion`` section's, with the settings it leaves to
        the measurement filled in (:func:`measurement_motion`)."""
        return measurement_motion(self.motion, self.measurement.name)

    @property
    def smoothing(self) -> int | None:
        """The run's smoothing lag (steps): :attr:`smoothing_lag`, else the measurement's
        default; ``None`` for no smoothing."""
        lag = self.smoothing_lag
        if lag is None:
            lag = MEASUREMENTS[self.measurement.name].default_smoothing_lag
        return lag or None

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The top-level keys: the sections, then the run's own keys."""
        return (*SECTIONS, *_own_keys())

    def to_dict(self) -> dict:
        """Plain JSON-ready dictionary of every setting, sections as objects with their
        ``name``; :meth:`from_dict` reads it back."""
        out = {section: getattr(self, section).to_dict() for section in SECTIONS}
        out.update({key: value for key, value in super().to_dict().items() if key in _own_keys()})
        return out

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "configuration") -> TrackingConfig:
        """Build from a configuration dictionary (the JSON shape of the module docstring),
        naming ``source``, the section and the key in any error."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a JSON object of settings, got {type(data)}")
        data = {k: v for k, v in data.items() if k not in DESCRIPTIVE_KEYS}
        unknown = sorted(set(data) - set(cls.keys()))
        if unknown:
            raise ValueError(
                f"{source}: unknown key(s) {unknown}; valid keys are {list(cls.keys())} (the "
                f"settings of the {', '.join(SECTIONS)} go in their sections)"
            )
        sections = {section: _section(data, section, source) for section in SECTIONS}
        try:
            return cls(**sections, **{k: v for k, v in data.items() if k not in SECTIONS})
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None

    @classmethod
    def from_json(cls, path: str | Path) -> TrackingConfig:
        """Read a configuration file (:func:`read_settings`)."""
        return cls.from_dict(read_settings(path), source=str(path))

    @classmethod
    def from_keys(cls, **keys) -> TrackingConfig:
        """Build from settings given by key, each put in its section (:func:`nest`), e.g.
        ``TrackingConfig.from_keys(period=8.0, measurement="arrival-time", n_particles=2000)``.
        """
        return cls.from_dict(nest(keys), source="settings")

    def override(self, **changes) -> TrackingConfig:
        """A validated copy with settings changed, given by key as in :meth:`from_keys`
        (``None`` values mean "not given"). Naming another measurement or motion model keeps
        the keys its settings share with the current ones (period, sound speed)."""
        layer = nest(changes)
        merged = self.to_dict()
        for section in SECTIONS:
            change = layer.pop(section, {})
            name = change.get("name", merged[section].get("name"))
            if name != merged[section].get("name"):
                # keep the shared keys, not the switches a newly named filter sets
                keys = set(section_classes(section)[name].keys()) - set(FILTERS.get(name, ()))
                merged[section] = {k: v for k, v in merged[section].items() if k in keys}
            merged[section] = merged[section] | change
        return TrackingConfig.from_dict(merged | layer, source="settings")


def _own_keys() -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(TrackingConfig) if f.name not in SECTIONS)


def _section(data: Mapping, section: str, source: str) -> Settings:
    raw = data.get(section, {})
    if not isinstance(raw, Mapping):
        raise ValueError(f"{source}: {section} must be a JSON object of settings, got {raw!r}")
    raw = section_default(data, section) | dict(raw)
    classes = section_classes(section)
    name = raw.pop("name")
    if name not in classes:
        raise ValueError(f"{source}: {section} name must be one of {list(classes)}, got {name!r}")
    where = f"{source}, section {section!r}" + ("" if name is None else f" ({name})")
    return classes[name].from_dict(raw, where)


def section_default(data: Mapping, section: str) -> dict:
    """What a configuration dictionary's ``section`` starts from, before its own keys: the
    component :data:`SECTIONS` names, or for the motion the measurement's ``default_motion``
    (its name and settings, e.g. the ping measurement's random walk) unless the motion
    section names another model, or for a filter section that names a filter of
    :data:`~hmmtrack.tracking.filter.FILTERS` (``"paper"``, ``"mode-keeping"``) that
    filter's switches, and for one that names none the switches of the measurement's filter
    in :data:`MEASUREMENT_FILTERS` (the ping measurement: ``"paper"``).

    Parameters
    ----------
    data : mapping
        A configuration dictionary (the JSON shape of the module docstring).
    section : str
        One of :data:`SECTIONS`.
    """
    default = {"name": SECTIONS[section]}
    measurement, motion = (data.get(key, {}) for key in ("measurement", "motion"))
    named = data.get("filter", {})
    measured = (
        measurement.get("name", SECTIONS["measurement"])
        if isinstance(measurement, Mapping)
        else None
    )
    if section == "filter" and isinstance(named, Mapping):
        name = named.get("name", MEASUREMENT_FILTERS.get(measured))
        if name in FILTERS:
            return {"name": name} | FILTERS[name]
    if section == "motion" and isinstance(measurement, Mapping) and isinstance(motion, Mapping):
        kind = MEASUREMENTS.get(measured)
        own = None if kind is None else kind.default_motion
        if own is not None and motion.get("name", own["name"]) == own["name"]:
            default = dict(own)
    return default


def nest(keys: Mapping) -> dict:
    """Settings given by key as a configuration dictionary: each key put in the section
    whose settings have it, ``"measurement"`` and ``"motion"`` as their section's name.

    Parameters
    ----------
    keys : mapping
        Keys of any section or of the run (every key names one setting); ``None`` values are
        left out.

    Returns
    -------
    dict
        ``{"measurement": {...}, "motion": {...}, "filter": {...}, ...}`` with only the
        sections given.

    Raises
    ------
    ValueError
        For a key of no section, listing the keys.
    """
    where = setting_sections()
    out: dict = {}
    for key, value in keys.items():
        if value is None:
            continue
        if key in SECTIONS:
            out.setdefault(key, {})["name"] = value
        elif key in where:
            section = where[key]
            if section is None:
                out[key] = value
            else:
                out.setdefault(section, {})[key] = value
        else:
            raise ValueError(f"unknown setting {key!r}; settings are {sorted(where)}")
    return out


def setting_sections() -> dict[str, str | None]:
    """The section of every setting's key (``None``: a key of the run itself)."""
    where: dict[str, str | None] = dict.fromkeys(_own_keys())
    for section in SECTIONS:
        for cls in section_classes(section).values():
            where.update(dict.fromkeys(cls.keys(), section))
    return where


def read_settings(path: str | Path) -> dict:
    """The JSON object of settings in ``path`` (keys unchecked: :meth:`TrackingConfig.from_dict`
    checks them), a relative motion ``model`` path and ``clocks`` path made relative to the
    file's folder."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object of settings")
    motion = data.get("motion")
    if isinstance(motion, dict) and isinstance(motion.get("model"), str):
        data["motion"] = motion | {"model": str(path.parent / motion["model"])}
    if isinstance(data.get("clocks"), str):
        data["clocks"] = str(path.parent / data["clocks"])
    return data


def merge_settings(*layers: Mapping) -> dict:
    """Configuration dictionaries ``layers`` (e.g. preset, file, command line) as one, later
    layers winning key by key, within sections too.

    ``None`` values mean "not given" and are skipped; ``r0`` mappings are merged receiver by
    receiver.
    """
    merged: dict = {}
    for layer in layers:
        for key, value in layer.items():
            if value is None:
                continue
            if key in SECTIONS and isinstance(value, Mapping):
                section = dict(merged.get(key, {}))
                for name, item in value.items():
                    if item is None:
                        continue
                    if name == "r0" and isinstance(item, Mapping):
                        item = dict(section.get("r0", {})) | dict(item)
                    section[name] = item
                value = section
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
        A configuration dictionary without the keys that describe data: combine it with
        the data's (:func:`merge_settings`) in :meth:`TrackingConfig.from_dict`.

    Raises
    ------
    ValueError
        For an unknown name (naming the available presets), or a preset with keys that
        describe data (its unknown keys :meth:`TrackingConfig.from_dict` refuses).
    """
    names = preset_names()
    if name not in names:
        raise ValueError(f"unknown preset {name!r}; available presets: {', '.join(names)}")
    path = PRESET_DIR / f"{name}.json"
    data = {k: v for k, v in read_settings(path).items() if k not in DESCRIPTIVE_KEYS}
    wrong = [key for key in data if _describes_data(TrackingConfig, key)]
    for section in SECTIONS:
        for key in data.get(section, {}):
            if any(_describes_data(cls, key) for cls in section_classes(section).values()):
                wrong.append(f"{section}.{key}")
    if wrong:
        raise ValueError(
            f"{path}: key(s) {sorted(wrong)} describe one data set, which a preset may not hold"
        )
    return data


def _describes_data(cls: type, key: str) -> bool:
    fields = {f.name: f for f in dataclasses.fields(cls)}
    return key in fields and bool(fields[key].metadata.get("data"))
