"""The scenario file's tables read into specs, in SI: the [imu] preset and datasheet
keys (``IMU_DATASHEET``: units in the key names, converted here), the sensors' tables
(a preset plus overrides), [indexer], the ``experiment`` key and the [[schedule]]
entries. Each raises a one-line ConfigError that names the bad key as the file writes
it. ``scenarios.config`` assembles them into a ``ScenarioConfig``.
"""
from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

from aligngym.models.indexer import IndexerSpec
from aligngym.models.schedule import Schedule, ScheduleEntry
from aligngym.models.units import (G0, arcsec, deg, deg_per_h, deg_per_sqrt_h,
                                   m_per_s_per_sqrt_h, ug)
from aligngym.scenarios.config_keys import (UNITS, ConfigError, _not_a_parameter, _to_si,
                                            _unknown_choice, _written_in, sensor_units)
from aligngym.sensors.imu import IMU_PRESETS, ImuSpec
from aligngym.sensors.suite import sensor_types


IMU_DATASHEET = {
    # key: (triad, TriadSpec field, factor to SI, upper bound in the key's unit)
    "gyro_bias_deg_h": ("gyro", "bias_sigma", deg_per_h, 1e4),
    "gyro_arw_deg_sqrt_h": ("gyro", "white_noise_density", deg_per_sqrt_h, 100.0),
    "gyro_bias_instability_deg_h": ("gyro", "bias_instability", deg_per_h, 1e4),
    "gyro_correlation_time_s": ("gyro", "correlation_time", 1.0, 1e6),
    "gyro_rate_random_walk_deg_h_sqrt_h": ("gyro", "random_walk", deg_per_h / 60.0, 1e4),
    "gyro_scale_factor_ppm": ("gyro", "scale_factor_sigma", 1e-6, 1e5),
    "gyro_misalignment_arcsec": ("gyro", "misalignment_sigma", arcsec, 3600.0),
    "gyro_quantization_arcsec": ("gyro", "quantization", arcsec, 3600.0),
    "gyro_range_deg_s": ("gyro", "measurement_range", deg, 1e5),
    "accel_bias_ug": ("accel", "bias_sigma", ug, 1e6),
    "accel_vrw_m_s_sqrt_h": ("accel", "white_noise_density", m_per_s_per_sqrt_h, 100.0),
    "accel_vrw_ug_sqrt_hz": ("accel", "white_noise_density", ug, 1e6),
    "accel_bias_instability_ug": ("accel", "bias_instability", ug, 1e6),
    "accel_correlation_time_s": ("accel", "correlation_time", 1.0, 1e6),
    "accel_random_walk_ug_sqrt_s": ("accel", "random_walk", ug, 1e6),
    "accel_scale_factor_ppm": ("accel", "scale_factor_sigma", 1e-6, 1e5),
    "accel_misalignment_arcsec": ("accel", "misalignment_sigma", arcsec, 3600.0),
    "accel_quantization_m_s": ("accel", "quantization", 1.0, 1.0),
    "accel_range_g": ("accel", "measurement_range", G0, 1e4),
}
"""[imu] datasheet keys, units in the names: bias repeatability (1 sigma, drawn per
episode), angle / velocity random walk, bias instability (the datasheet's, Allan floor /
0.664) with the correlation time of its Gauss-Markov model, rate / acceleration random
walk, scale factor and axis misalignment (1 sigma), the increment's LSB, the measurement
range. Each value in [0, bound] (correlation time and range > 0)."""


def _imu_spec(table: dict[str, Any]) -> tuple[str, ImuSpec]:
    """The [imu] table: a preset plus datasheet overrides, or a full datasheet (no preset:
    every error not given is 0). Returns (preset name or "datasheet", the spec)."""
    values = dict(table)
    preset = values.pop("preset", None)
    if preset is not None and preset not in IMU_PRESETS:
        raise _unknown_choice("imu.preset", preset, IMU_PRESETS)
    if preset is None and not values:
        raise ConfigError("[imu] needs a preset (" + ", ".join(sorted(IMU_PRESETS))
                          + ") or datasheet keys (" + ", ".join(IMU_DATASHEET) + ")")
    spec = IMU_PRESETS[preset] if preset is not None else ImuSpec()
    changes: dict[str, dict[str, float]] = {"gyro": {}, "accel": {}}
    for key, value in values.items():
        if key not in IMU_DATASHEET:
            raise _not_a_parameter(f"imu.{key}", key,
                                   ["bias_frame", "preset", *IMU_DATASHEET])
        triad, name, factor, bound = IMU_DATASHEET[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"imu.{key} must be a number, got {value!r}")
        positive = name in ("correlation_time", "measurement_range")
        if not (0.0 < value if positive else 0.0 <= value) or not value <= bound:
            raise ConfigError(f"imu.{key} = {value:g} is out of range "
                              f"{'(0' if positive else '[0'}, {bound:g}]")
        if name in changes[triad]:
            raise ConfigError(f"imu.{key}: the {triad} {name.replace('_', ' ')} is given "
                              "twice")
        changes[triad][name] = float(value) * factor
    if changes["gyro"] or changes["accel"]:
        spec = ImuSpec(gyro=replace(spec.gyro, **changes["gyro"]),
                       accel=replace(spec.accel, **changes["accel"]))
    return preset or "datasheet", spec


def _experiment_key(name: str) -> str:
    """The file's experiment key, checked against the registered experiments."""
    from aligngym.scenarios.registry import experiment_names
    if name and name not in experiment_names():
        raise _unknown_choice("experiment", name, experiment_names())
    return name


def _dataclass_from(cls, values: dict[str, Any], section: str,
                    units: dict[str, str] = UNITS):
    """cls(**values) with errors that name the section's field as the file writes it
    (units: its keys' suffixes)."""
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        written = unknown[0] + units.get(unknown[0], "")
        raise _not_a_parameter(f"{section}.{written}", written,
                               sorted(k + units.get(k, "") for k in known))
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        message = _written_in(str(exc), section, units)
        raise ConfigError(message if message.startswith(f"{section}.")
                          else f"{section}: {message}") from None


def _indexer(table: dict[str, Any]) -> IndexerSpec:
    """The azimuth indexer from its [indexer] table (SI; schedule rows [time_s, angle_deg]
    converted here)."""
    table = dict(table)
    if "schedule" in table:
        try:
            table["schedule"] = tuple((float(t), float(a) * deg) for t, a in table["schedule"])
        except (TypeError, ValueError):
            raise ConfigError("indexer.schedule must be a list of [time_s, angle_deg] rows")
    return _dataclass_from(IndexerSpec, table, "indexer")


def _sensor(values: dict[str, Any], presets: dict, cls, section: str,
            units: dict[str, str] = UNITS):
    """A sensor spec from its table: a preset plus overrides (an empty table: the
    spec's defaults)."""
    values = dict(values)
    preset = values.pop("preset", None)
    if preset is not None and preset not in presets:
        if not presets:
            raise ConfigError(f"{section}.preset = {preset!r}: [{section}] has no presets; "
                              "give its keys")
        raise _unknown_choice(f"{section}.preset", preset, presets)
    base = {f.name: getattr(presets[preset], f.name) for f in fields(cls)} if preset else {}
    if "pulses_per_rev" in values:
        values["pulses_per_rev"] = int(values["pulses_per_rev"])
    return _dataclass_from(cls, {**base, **values}, section, units)


def _plugged_sensor(raw: dict[str, Any], name: str, source: str):
    """The spec of a registered sensor's table (``sensors.base.register_sensor``): its
    preset plus overrides, keys in its own units."""
    cls = sensor_types()[name]
    if not isinstance(raw[name], dict):
        raise ConfigError(f"{source}: [{name}] must be a table")
    return _sensor(_to_si(raw[name], name, cls.units), cls.presets, cls.spec_type, name,
                   cls.units)


SCHEDULED_IMU = ("gyro_arw_deg_sqrt_h", "accel_vrw_m_s_sqrt_h", "accel_vrw_ug_sqrt_hz")
"""The [imu] keys a [[schedule]] entry may change (the white noise: a vibration burst)."""


def _schedule(rows: Any, source: str, specs: dict[str, Any], imu: ImuSpec, world,
              motion, motion_units: dict[str, str]) -> Schedule:
    """The [[schedule]] list: per entry its time_s, ramp_s (0 if absent) and, per table it
    changes (imu, the world's [motion] where it has schedulable fields, or a sensor of the
    scenario with schedulable fields), the new values in that table's units; each
    checked by the table's own spec."""
    if not (isinstance(rows, list) and all(isinstance(row, dict) for row in rows)):
        raise ConfigError(f"{source}: schedule must be a list of [[schedule]] tables")
    entries = []
    for i, row in enumerate(rows):
        where, row = f"schedule[{i}]", dict(row)
        if "time_s" not in row:
            raise ConfigError(f"{source}: {where} has no time_s")
        timing = _to_si({k: row.pop(k) for k in ("time_s", "ramp_s") if k in row}, where,
                        {"time": "_s", "ramp": "_s"})
        if not row:
            raise ConfigError(f"{where} changes nothing; give new values of a table, e.g. "
                              "gps.position_sigma_h_m = 2.5")
        for section, table in row.items():
            if not isinstance(table, dict):
                raise ConfigError(f"{where}.{section} must be a table's keys, e.g. "
                                  f"{section}.name = value")
            if section == "imu":
                values = _scheduled_imu(table, f"{where}.imu", imu)
            elif section == "motion" and world.schedulable:
                values = _scheduled_fields(table, f"{where}.motion", "motion", motion,
                                           world.schedulable, motion_units)
            else:
                values = _scheduled_sensor(table, f"{where}.{section}", section, specs,
                                           world)
            entries.append(ScheduleEntry(timing["time"], timing.get("ramp", 0.0), section,
                                         tuple(sorted(values.items())), where))
    return Schedule(tuple(entries))


def _scheduled_sensor(table: dict[str, Any], where: str, section: str,
                      specs: dict[str, Any], world) -> dict[str, float]:
    """A schedule entry's new values (SI) for the scenario's sensor ``section``."""
    can = {name: sensor_types()[name].schedulable for name in specs
           if sensor_types()[name].schedulable}
    if section not in can:
        tables = ["imu", *(["motion"] if world.schedulable else []), *can]
        raise _unknown_choice(where.rsplit(".", 1)[0] + " table", section, tables)
    return _scheduled_fields(table, where, section, specs[section], can[section],
                             sensor_units(section))


def _scheduled_fields(table: dict[str, Any], where: str, section: str, spec: Any,
                      schedulable: tuple[str, ...], units: dict[str, str]
                      ) -> dict[str, float]:
    """A schedule entry's new values (SI) of a spec's schedulable fields, checked by the
    spec itself (its own checks, and ``check()`` where it has one)."""
    values = _to_si(table, where, units)
    valid = sorted(name + units.get(name, "") for name in schedulable)
    for name in values:
        if name not in schedulable:
            written = name + units.get(name, "")
            raise _not_a_parameter(f"{where}.{written}", written, valid,
                                   " a schedule may change")
    try:
        changed = replace(spec, **values)
        if callable(getattr(changed, "check", None)):
            changed.check()
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where.rsplit('.', 1)[0]}: "
                          + _written_in(str(exc), section, units)) from None
    return values


def _scheduled_imu(table: dict[str, Any], where: str, imu: ImuSpec) -> dict[str, float]:
    """A schedule entry's new white-noise densities of the IMU, SI, by
    "gyro.white_noise_density" / "accel.white_noise_density"."""
    values: dict[str, float] = {}
    for key, value in table.items():
        if key not in SCHEDULED_IMU:
            raise _not_a_parameter(f"{where}.{key}", key, list(SCHEDULED_IMU),
                                   " a schedule may change")
        triad, name, factor, bound = IMU_DATASHEET[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                0.0 <= value <= bound):
            raise ConfigError(f"{where}.{key} = {value!r} is out of range [0, {bound:g}]")
        if f"{triad}.{name}" in values:
            raise ConfigError(f"{where}.{key}: the {triad} white noise is given twice")
        values[f"{triad}.{name}"] = float(value) * factor
    return values
