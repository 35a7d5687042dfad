"""An experiment's settings declared once: ``setting`` and ``bounded`` (a dataclass field
with its doc, unit, choices or range), and ``validate_settings``, which checks every
value against its type and declaration when the experiment is made (one
``config.SettingError`` naming the setting and its allowed range)."""
from __future__ import annotations

import types
import typing
from dataclasses import field, fields
from typing import Any

import numpy as np

from aligngym.scenarios.config import SettingError


def setting(default: Any, doc: str, *, unit: str = "", choices: tuple = (),
            sweep: bool = False, low: float | None = None, high: float | None = None,
            low_open: bool = False, option: bool = True, minimum: float | None = None
            ) -> Any:
    """A declared setting of an experiment: a dataclass field whose metadata holds its doc
    (the option's help), its unit, the values it takes (choices) or its range (numbers, and
    each number of a tuple: low <= value <= high, low < value with low_open; minimum: an
    older name of low), and sweep (with choices: the option also takes "all", one campaign
    per choice, ``Experiment.merge_sweep`` joins their summaries). With option (the
    default) ``bench`` offers it as ``--NAME`` (underscores as dashes); every setting is
    also ``--set NAME=VALUE``. ``validate_settings`` checks every value against its field's
    type and this declaration when the experiment is made."""
    return field(default=default, metadata={
        "doc": doc, "unit": unit, "choices": tuple(choices), "sweep": sweep,
        "low": low if low is not None else minimum, "high": high, "low_open": low_open,
        "option": option})


def bounded(default: Any, unit: str = "", *, low: float | None = None,
            high: float | None = None, low_open: bool = False, choices: tuple = ()) -> Any:
    """A setting without an option of its own (``--set NAME=VALUE`` only) with a declared
    range or choices (see ``setting``)."""
    return setting(default, "", unit=unit, choices=choices, low=low, high=high,
                   low_open=low_open, option=False)


POSITIVE = {"low": 0.0, "low_open": True}
"""``bounded(x, "s", **POSITIVE)``: a number > 0."""
MAX_RUN = 86400.0
"""s: the longest run a scenario takes (``config.ScenarioConfig.validate``)."""


def _whole(ratio: float) -> bool:
    return abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, (bool, np.bool_)))


def _range_text(meta: dict) -> str:
    low, high, unit = meta.get("low"), meta.get("high"), meta.get("unit", "")
    if low is not None and high is not None:
        text = f" in {'(' if meta.get('low_open') else '['}{low:g}, {high:g}]"
    elif low is not None:
        text = f" {'>' if meta.get('low_open') else '>='} {low:g}"
    elif high is not None:
        text = f" <= {high:g}"
    else:
        text = ""
    return text + (f" {unit}" if unit and text else "")


def _in_range(value: float, meta: dict) -> bool:
    low, high = meta.get("low"), meta.get("high")
    if low is not None and not (value > low if meta.get("low_open") else value >= low):
        return False
    return high is None or value <= high


def _check_value(name: str, value: Any, kind: Any, meta: dict, default: Any) -> Any:
    """The value, checked against its field's type (kind) and declaration (meta); a list
    for a tuple becomes a tuple. A SettingError naming the setting otherwise."""
    optional = False
    if typing.get_origin(kind) in (types.UnionType, typing.Union):
        args = typing.get_args(kind)
        optional = type(None) in args
        rest = [a for a in args if a is not type(None)]
        kind = rest[0] if len(rest) == 1 else None
    if value is None:
        if optional or kind is None:
            return value
        raise SettingError(name, value, f"must be {_expected(kind, meta)}, got none")
    tail = " or none" if optional else ""
    choices = meta.get("choices") or ()
    if choices and value != default and value not in choices:
        raise SettingError(name, value, f"must be one of {', '.join(map(str, choices))}"
                                        f"{tail}, got {value!r}")
    if kind in (float, int):
        if not _is_number(value) or (kind is int and not float(value).is_integer()):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        if not (np.isfinite(value) and _in_range(float(value), meta)):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    if kind in (str, bool):
        if not isinstance(value, kind):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        count = None if len(args) == 2 and args[1] is Ellipsis else len(args)
        item = args[0] if args else None
        ok = isinstance(value, (tuple, list)) and (count is None or len(value) == count)
        if ok:
            try:
                value = tuple(_check_value(name, v, item, meta, None) for v in value)
            except Exception:
                ok = False
        if not ok:
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    return value


def _expected(kind: Any, meta: dict) -> str:
    """What a value of this type and declaration must be, in words."""
    if kind is float:
        return "a finite number" + _range_text(meta)
    if kind is int:
        return "an integer" + _range_text(meta)
    if kind is str:
        return "a string"
    if kind is bool:
        return "true or false"
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_expected(args[0], meta).removeprefix('a ')}s"
        return f"a list of {len(args)} " + _expected(args[0], meta).removeprefix(
            "a ").replace("number", "numbers", 1)
    return "a valid value"


def validate_settings(cls: type, experiment: Any) -> None:
    """Every setting of an experiment (a frozen dataclass) checked, in one place, before
    any work: its type (a bool or a string is not a number; numbers finite; tuples of the
    declared length), its declared choices and range (``setting``, ``bounded``), and the
    filter step against the fine run (0 < filter_step <= fine_duration). A list for a
    tuple becomes a tuple. Raises the first ``config.SettingError``."""
    hints = cls.__dict__.get("_setting_types")
    if hints is None:
        try:
            hints = typing.get_type_hints(cls)
        except Exception:             # an unresolvable annotation: types left unchecked
            hints = {}
        cls._setting_types = hints
    for f in fields(cls):
        value = getattr(experiment, f.name)
        checked = _check_value(f.name, value, hints.get(f.name), dict(f.metadata), f.default)
        if checked is not value:
            object.__setattr__(experiment, f.name, checked)
    step = getattr(experiment, "filter_step", None)
    fine = getattr(experiment, "fine_duration", None)
    if _is_number(step) and _is_number(fine) and step > fine:
        defaults = {f.name: f.default for f in fields(cls)}
        if step == defaults.get("filter_step"):          # name the one that was changed
            raise SettingError("fine_duration", fine, f"must be >= {{other}} ({step:g} s), "
                                                      f"got {fine!r}", other="filter_step")
        raise SettingError("filter_step", step, f"must be <= {{other}} ({fine:g} s), "
                                                f"got {step!r}", other="fine_duration")
