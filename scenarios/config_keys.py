"""The keys of scenario files: each parameter's unit suffix, the conversion of a table to
SI, the kind checks, and the one-line errors that name a key as the file writes it
(``run.duration_s``) with the closest valid key or choice."""
from __future__ import annotations

import difflib
import math
import re
from typing import Any

from aligngym.models.units import arcsec, deg
from aligngym.scenarios.worlds import check_range
from aligngym.sensors.suite import sensor_types

# Key suffix -> factor to SI, longest suffix first.
_UNIT_SUFFIXES = (("_deg_s", deg), ("_arcsec", arcsec), ("_deg", deg), ("_hz", 1.0),
                  ("_m", 1.0), ("_s", 1.0))
_UNIT_NAMES = {"_deg_s": "deg/s", "_arcsec": "arcsec", "_deg": "deg", "_hz": "Hz",
               "_m": "m", "_s": "s"}

UNITS = {
    # origin, run
    "latitude": "_deg", "longitude": "_deg", "height": "_m", "duration": "_s",
    "imu_rate": "_hz",
    # encoder
    "resolution": "_arcsec", "offset_sigma": "_arcsec",
    # prescribed ship
    "yaw_mean": "_deg", "yaw_amplitude": "_deg", "yaw_period": "_s", "yaw_phase": "_deg",
    "pitch_amplitude": "_deg", "pitch_period": "_s", "pitch_phase": "_deg",
    "roll_amplitude": "_deg", "roll_period": "_s", "roll_phase": "_deg",
    "linear_amplitude": "_m", "linear_period": "_s", "linear_phase": "_deg", "sway_scale": "",
    "lever_arm_b": "_m", "gimbal_outer_rate": "_deg_s", "gimbal_inner_rate": "_deg_s",
    "antenna_b": "_m", "hull_size": "_m",
    # azimuth indexer (rotor_inertia kg m^2; schedule rows [time_s, angle_deg])
    "stops": "_deg", "dwell": "_s", "slew_rate": "_deg_s", "schedule": "",
    "natural_frequency": "_hz", "rotor_inertia": "", "servo_step": "_s",
    # wave-driven ship
    "significant_wave_height": "_m", "peak_period": "_s", "peak_enhancement": "",
    "wave_direction": "_deg", "components": "", "heave_period": "_s",
    "damping_ratio": "", "heading": "_deg",
    # car (speed m/s and accel m/s^2 carry no suffix)
    "track": "", "radius": "_m", "speed": "", "start_time": "_s", "stop_time": "_s",
    "accel": "", "roughness_rms": "_m", "imu_offset_b": "_m", "gps_antenna_b": "_m",
    # static platform
    "yaw": "_deg", "pitch": "_deg", "roll": "_deg",
    # GPS (velocity_sigma and heading_min_speed in m/s, no suffix)
    "rate": "_hz", "position_sigma_h": "_m", "position_sigma_v": "_m",
    "velocity_sigma": "", "heading_min_speed": "", "latency": "_s", "outages": "_s",
    "multipath_dof": "",
    "outliers": "", "slips": "",
    # IMU data faults (rows: see sensors.faults)
    "spikes": "", "saturation": "", "gaps": "", "nans": "", "gimbal_stalls": "",
    # odometer
    "pulses_per_rev": "", "nominal_radius": "_m", "scale_error": "",
    "scale_error_sigma": "", "mounting_pitch": "_deg", "mounting_heading": "_deg",
    # imu, filter
    "preset": "", "bias_frame": "", "euler_sigma": "_deg", "initial_covariance": "",
}
"""Each parameter's unit suffix in scenario files ("": none); a key's suffix is part of
its name, so pitch_period_deg is an error, not a period in degrees."""

VECTORS = ("linear_amplitude", "linear_period", "linear_phase", "lever_arm_b",
           "imu_offset_b", "gps_antenna_b", "euler_sigma", "antenna_b", "hull_size")
"""Parameters of 3 values (E, N, U or R, F, U)."""
STRINGS = ("preset", "bias_frame", "track")
INTEGERS = ("components", "pulses_per_rev")
FREE = ("outages", "outliers", "slips", "initial_covariance", "stops", "schedule",
        "spikes", "saturation", "gaps", "nans", "gimbal_stalls")
"""Checked by their users: (start, end) windows; (time s, east m, north m, up m) and
(time s, duration s, extra m) rows; a matrix; the indexer's stops and schedule rows."""

SECTIONS = ("origin", "run", "imu", "motion", "encoder", "odometer", "gps", "filter",
            "indexer", "faults")
TOP_KEYS = ("name", "paper", "experiment", "world")


class ConfigError(ValueError):
    """An invalid scenario or option; the message names the field and the allowed range."""


def _to_si(table: dict[str, Any], section: str, units: dict[str, str] = UNITS
           ) -> dict[str, Any]:
    """Strip unit suffixes from keys and convert their values to SI; a known parameter
    must carry its own unit suffix (units: ``UNITS``, or a registered sensor's), numbers
    must be finite and not booleans."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        name, factor, written = key, 1.0, ""
        for suffix, scale in _UNIT_SUFFIXES:
            if key.endswith(suffix) and key[: -len(suffix)] in units:
                name, factor, written = key[: -len(suffix)], scale, suffix
                break
        if name in units and units[name] != written and not (
                written == "" and isinstance(value, str)):   # e.g. linear_phase = "random"
            unit = units[name]
            raise ConfigError(
                f"{section}.{key}: {name} "
                + (f"is in {_UNIT_NAMES[unit]}; write {name}{unit}" if unit else
                   f"takes no unit suffix; write {name}"))
        if name in out:
            raise ConfigError(f"{section}.{key}: {name} is given twice")
        try:   # unknown keys keep their name as written: the section's check names it
            out[name] = _scale(value, factor) if written else _checked(value)
        except (TypeError, ValueError, OverflowError) as exc:
            raise ConfigError(f"{section}.{key}: {exc}") from None
        _check_kind(f"{section}.{key}", name, out[name])
    return out


def _check_kind(field: str, name: str, value: Any) -> None:
    """A known parameter's value has its kind: 3 numbers, a string, an integer or a
    number (``VECTORS``, ``STRINGS``, ``INTEGERS``; ``FREE`` ones and a registered
    sensor's or world's own are checked by their dataclass)."""
    if name not in UNITS or name in FREE:
        return
    if name == "linear_phase" and value == "random":
        return
    if name in VECTORS:
        ok = (isinstance(value, tuple) and len(value) == 3
              and all(isinstance(v, float) for v in value))
        expected = "3 numbers"
    elif name in STRINGS:
        ok, expected = isinstance(value, str), "a string"
    elif name in INTEGERS:
        ok, expected = isinstance(value, int) and not isinstance(value, bool), "an integer"
    else:
        ok, expected = isinstance(value, (int, float)) and not isinstance(value, bool), \
            "a number"
    if not ok:
        raise ConfigError(f"{field} must be {expected}, got {value!r}")


def _scale(value: Any, factor: float) -> Any:
    """A number, or nested lists of numbers, times factor (lists become tuples)."""
    if isinstance(value, list):
        return tuple(_scale(v, factor) for v in value)
    return _number(value) * factor


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"expected a number or a list of numbers, got {value!r}")
    if not math.isfinite(value) or abs(value) > 1e300:
        raise ValueError(f"must be finite, got {value!r}")
    return float(value)


def _checked(value: Any) -> Any:
    """A value without unit: strings pass; numbers (in lists) must be finite, not bool."""
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        return tuple(_checked(v) for v in value)
    return value if isinstance(value, int) and not isinstance(value, bool) else _number(value)


def _key(section: str, name: str) -> str:
    """A parameter's key as a scenario file writes it, unit suffix included
    (``run.duration_s``): what its errors name."""
    return f"{section}.{name}{UNITS.get(name, '')}"


_FIELD = re.compile(r"\b(" + "|".join(SECTIONS) + r")\.([A-Za-z_][A-Za-z0-9_]*)")


def _as_written(message: str) -> str:
    """A message from a sensor's or a world's own check with each ``section.field`` it
    names written as the file writes the key (``motion.heave_period`` ->
    ``motion.heave_period_s``). A key in deg or arcsec is renamed only where the message
    gives its value in that unit (a check that reports radians keeps the SI name: a
    radian under a _deg key would mislead)."""
    def written(match: re.Match) -> str:
        name = match.group(2)
        suffix = UNITS.get(name)
        if suffix is None:
            return match.group(0)
        if _UNIT_NAMES.get(suffix, "") not in ("", "m", "s", "Hz") and (
                f" {_UNIT_NAMES[suffix]}" not in message or "SI units" in message):
            return match.group(0)
        return _key(match.group(1), name)
    return _FIELD.sub(written, message)


def _unknown_choice(field: str, value: Any, choices) -> ConfigError:
    """The one-line error for a value outside its choices: the closest choice if one is
    close, then every choice."""
    choices = sorted(choices)
    close = (difflib.get_close_matches(value, choices, n=1, cutoff=0.6)
             if isinstance(value, str) else [])
    return ConfigError(f"{field} = {value!r} is unknown; "
                       + (f"did you mean {close[0]!r}? " if close else "")
                       + "valid choices: " + ", ".join(choices))


def _not_a_parameter(field: str, written: str, valid: list[str], what: str = ""
                     ) -> ConfigError:
    """The one-line error for an unknown key: the field as written, the closest valid key
    if one is close, then every valid key."""
    close = difflib.get_close_matches(written, valid, n=1, cutoff=0.6)
    return ConfigError(f"{field} is not a parameter{what}; "
                       + (f"did you mean {close[0]}? " if close else "")
                       + "valid: " + ", ".join(valid))


class SettingError(ConfigError):
    """An experiment setting's value refused before any work: ``name`` (the setting, a
    field of the experiment), ``value`` and ``detail`` ("must be ..., got ..."; "{other}"
    in it stands for the setting ``other`` it was compared with). str() names the
    settings by their fields; ``as_written(label)`` is the same one line naming them as
    the user wrote them (label: field name -> "--set NAME", "--NAME", "NAME=", ...)."""

    def __init__(self, name: str, value: Any, detail: str, other: str = "") -> None:
        self.name, self.value, self.detail, self.other = name, value, detail, other
        super().__init__(f"{name} {detail.replace('{other}', other)}")

    def as_written(self, label) -> ConfigError:
        return ConfigError(f"{label(self.name)} "
                           + self.detail.replace("{other}", label(self.other)))


def _check_range(field: str, value: float, low: float, high: float, unit: str,
                 low_open: bool = False) -> None:
    try:
        check_range(field, value, low, high, unit, low_open)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None


def sensor_units(section: str) -> dict[str, str]:
    """The unit suffixes of a sensor table's keys (a registered sensor's own, else
    ``UNITS``)."""
    cls = sensor_types().get(section)
    return UNITS if cls is None or section in SECTIONS else cls.units


def _written_in(message: str, section: str, units: dict[str, str]) -> str:
    """A message naming ``section.field`` with each such field written as the file writes
    its key (``dvl.rate`` -> ``dvl.rate_hz``; ``_as_written`` for the file's own
    tables)."""
    if units is UNITS:
        return _as_written(message)
    return re.sub(rf"\b{section}\.([A-Za-z_][A-Za-z0-9_]*)",
                  lambda m: f"{section}.{m.group(1)}{units.get(m.group(1), '')}", message)
