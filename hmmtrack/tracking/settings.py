"""Settings of the tracker's components: fields that carry their own check, help and option.

Each component of a tracking run declares its settings as a frozen dataclass next to it
(:class:`hmmtrack.tracking.filter.FilterSettings`, the measurements' and motion models'
settings), every field made by :func:`setting`: its default, the check that validates and
normalises a value (from a JSON file, a Python call or the command line alike), a help
text, and how the command line spells it. :class:`Settings` is their common base: it runs
the checks when an instance is built, reads a section of a configuration file refusing
unknown keys (:meth:`Settings.from_dict`) and writes it back (:meth:`Settings.to_dict`).
:mod:`hmmtrack.tracking.config` composes the sections into one run's configuration, and
``hmmtrack track`` generates its options from the same fields, so that every default lives
in one place.

The checks below are the shared ones; each raises ``ValueError`` naming the key and the
value refused.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import pandas as pd

__all__ = [
    "Settings",
    "boolean",
    "fraction",
    "instant",
    "non_negative",
    "number",
    "one_of",
    "non_negative_integer",
    "positive",
    "positive_integer",
    "setting",
    "text",
]


def setting(
    default: Any = dataclasses.MISSING,
    *,
    help: str,
    check: Callable[[str, Any], Any] | None = None,
    default_factory: Callable[[], Any] | Any = dataclasses.MISSING,
    option: str | None = None,
    parse: Callable[[str], Any] = str,
    metavar: str | tuple[str, ...] | None = None,
    nargs: int | None = None,
    choices: tuple[str, ...] | None = None,
    append: bool = False,
    requires: tuple[str, Any] | None = None,
    data: bool = False,
    default_text: str | None = None,
):
    """A settings field.

    Parameters
    ----------
    default, default_factory
        As :func:`dataclasses.field`; no default makes the key required.
    help : str
        What the setting is, with its unit (help text of its command-line option).
    check : callable, optional
        ``check(name, value) -> value``: the validated, normalised value; raises
        ``ValueError`` naming ``name``. Not called on ``None`` when the default is ``None``
        (not given).
    option : str, optional
        Command-line option without the dashes; by default the key with ``-`` for ``_``.
    parse : callable
        ``parse(text)`` of one command-line word before ``check`` (``float``, ``int``, ...).
    metavar, nargs, choices
        As :meth:`argparse.ArgumentParser.add_argument`.
    append : bool
        A mapping given on the command line one item at a time (the option repeated), each
        parsed to a ``(key, value)`` pair.
    requires : (key, value), optional
        The setting is used only when the section's ``key`` is ``value`` (giving it
        otherwise on the command line is an error).
    data : bool
        The setting describes one data set (period, known ranges, ...): a preset may not
        hold it.
    default_text : str, optional
        The default as the help text says it, when ``None`` stands for a value chosen
        elsewhere (e.g. by the motion model's variant).
    """
    metadata = {
        "help": help,
        "check": check,
        "option": option,
        "parse": parse,
        "metavar": metavar,
        "nargs": nargs,
        "choices": choices,
        "append": append,
        "requires": requires,
        "data": data,
        "default_text": default_text,
    }
    return dataclasses.field(default=default, default_factory=default_factory, metadata=metadata)


@dataclasses.dataclass(frozen=True)
class Settings:
    """Base of the settings classes: checks fields on construction, reads and writes dicts.

    A subclass is a frozen dataclass of :func:`setting` fields; it may set :attr:`name` (the
    component's name in its registry, written as the section's ``"name"`` key) and override
    :meth:`validate` for checks across its fields.
    """

    name: ClassVar[str | None] = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            check = f.metadata.get("check")
            value = getattr(self, f.name)
            if check is None or (value is None and f.default is None):
                continue
            object.__setattr__(self, f.name, check(f.name, value))
        self.validate()

    def validate(self) -> None:
        """Checks across fields (none by default); raise ``ValueError`` naming the keys."""

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The keys of this section."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "settings") -> Settings:
        """Build from a section's keys; unknown or missing keys are refused, naming
        ``source`` and listing the valid keys."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a JSON object of settings, got {data!r}")
        valid = cls.keys()
        unknown = sorted(set(data) - set(valid))
        if unknown:
            raise ValueError(f"{source}: unknown key(s) {unknown}; valid keys are {list(valid)}")
        missing = [
            f.name
            for f in dataclasses.fields(cls)
            if f.default is dataclasses.MISSING
            and f.default_factory is dataclasses.MISSING
            and f.name not in data
        ]
        if missing:
            raise ValueError(f"{source}: missing required key(s) {missing}")
        try:
            return cls(**data)
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None

    def to_dict(self) -> dict:
        """Plain JSON-ready dictionary (``name`` first when the class has one);
        :meth:`from_dict` reads it back."""
        out = {} if self.name is None else {"name": self.name}
        for f in dataclasses.fields(self):
            out[f.name] = _plain(getattr(self, f.name))
        return out


def _plain(value):
    """``value`` as JSON types: tuples as lists, mappings as dicts, settings as dicts."""
    if isinstance(value, Settings):
        return {k: v for k, v in value.to_dict().items() if k != "name"}
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


# ---------------------------------------------------------------------------- checks


def number(name: str, value) -> float:
    """A finite number."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        result = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(result):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return result


def positive(name: str, value) -> float:
    """A positive finite number."""
    result = number(name, value)
    if result <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return result


def non_negative(name: str, value) -> float:
    """A finite number ≥ 0."""
    result = number(name, value)
    if result < 0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return result


def fraction(name: str, value) -> float:
    """A number in ``(0, 1]``."""
    result = number(name, value)
    if not 0 < result <= 1:
        raise ValueError(f"{name} must lie in (0, 1], got {value!r}")
    return result


def _whole_number(name: str, value, lowest: int, what: str) -> int:
    """``value`` as an int when it is a whole number ≥ ``lowest`` (an integral float such as
    5000.0 included); else a ValueError saying it must be ``what``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or value != int(value)
        or value < lowest
    ):
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return int(value)


def positive_integer(name: str, value) -> int:
    """A whole number ≥ 1 (an integral float such as 5000.0 included)."""
    return _whole_number(name, value, 1, "a positive integer")


def non_negative_integer(name: str, value) -> int:
    """A whole number ≥ 0 (an integral float included)."""
    return _whole_number(name, value, 0, "a whole number >= 0")


def boolean(name: str, value) -> bool:
    """``true`` or ``false``."""
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, got {value!r}")
    return value


def text(name: str, value) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value:
        raise ValueError(f"{name} must be a non-empty string, got {value!r}")
    return value


def one_of(*choices: str) -> Callable[[str, Any], str]:
    """The check that a value is one of ``choices``."""

    def check(name: str, value) -> str:
        if value not in choices:
            raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")
        return value

    return check


def instant(name: str, value) -> float:
    """UTC epoch seconds, or ISO 8601 text with a UTC offset, as epoch seconds."""
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
    return number(name, value)
