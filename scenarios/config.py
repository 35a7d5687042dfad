"""Scenario files (TOML, units in the key names) loaded into typed, validated configs.

``ScenarioConfig`` is a scenario in SI and its validation; ``load_scenario`` reads a file
(a shipped scenario's name or a .toml path), checks its keys and tables and assembles
the config from the tables' readers (``scenarios.config_tables``).
"""
from __future__ import annotations

import difflib
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from aligngym.models.schedule import Schedule
from aligngym.models.units import deg
from aligngym.scenarios.config_keys import (SECTIONS, TOP_KEYS, UNITS,  # noqa: F401
                                            ConfigError, SettingError, _as_written,
                                            _check_range, _key, _not_a_parameter, _to_si,
                                            _unknown_choice, _written_in, sensor_units)
from aligngym.scenarios.config_tables import (_dataclass_from, _experiment_key, _imu_spec,
                                              _indexer, _plugged_sensor, _schedule, _sensor)
from aligngym.scenarios.registry import DATA_DIR, scenario_names  # noqa: F401  (re-exported)
from aligngym.scenarios.worlds import WORLDS, UnknownMotionKey, world_named
from aligngym.sensors.encoder import GimbalEncoderSpec
from aligngym.sensors.faults import ImuFaults
from aligngym.sensors.gps import GPS_PRESETS, GpsSpec
from aligngym.sensors.imu import ImuSpec
from aligngym.sensors.odometer import ODOMETER_PRESETS, OdometerSpec
from aligngym.sensors.suite import SensorSuite, sensor_types

BIAS_FRAMES = ("sensor", "hull")


@dataclass(frozen=True)
class ScenarioConfig:
    """A scenario in SI: origin lat/lon (rad) and height (m), duration (s), IMU rate (Hz),
    IMU datasheet, encoder spec and the world's motion parameters."""

    name: str
    paper: str
    world: str
    latitude: float
    longitude: float
    height: float
    duration: float
    imu_rate: float
    imu_preset: str
    imu: ImuSpec
    encoder: GimbalEncoderSpec
    motion: Any
    """The world's [motion] (its ``motion_type``: ShipSwayMotion, VehicleMotion,
    WaveShipMotion, StaticPlatformMotion or a registered world's)."""
    random_linear_phase: bool
    odometer: OdometerSpec | None = None
    gps: GpsSpec | None = None
    imu_bias_frame: str = "sensor"
    """Frame in which the drawn constant biases are constant: "sensor" (they turn with a
    rotary IMU, which modulates them) or "hull" (no modulation)."""
    filter: tuple[tuple[str, Any], ...] = ()
    """The [filter] table (SI, unit suffixes stripped): tuning overrides that the
    scenario's experiment validates (e.g. paper 002's initial_covariance)."""
    faults: ImuFaults = ImuFaults()
    sensors: tuple[tuple[str, Any], ...] = ()
    """The registered sensors without a field of their own (``sensors.base``), as
    (section, spec) pairs in their registration order: a [dvl] table, a user's sensor.
    Specs are in SI (the file's _deg and _arcsec keys converted to rad)."""
    schedule: Schedule = Schedule()
    """The disturbances that change within the episode ([[schedule]]: the GNSS
    receiver's sigmas and multipath, the IMU's white noise, the wave-driven ship's sea
    state), SI."""
    experiment: str = ""
    """The pipeline that runs on this scenario (the file's ``experiment`` key, e.g.
    "paper003"; "" for none): the only map from a scenario to its experiment."""
    source: str = field(default="", compare=False)
    """The file it was read from."""

    def with_options(self, duration: float | None = None, imu_rate: float | None = None,
                     labels: dict[str, str] | None = None) -> "ScenarioConfig":
        """Copy with command-line overrides, validated; labels: the name an error gives
        an overridden field ({"duration": "--duration"}; default: its file key)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        if duration is not None:
            values["duration"] = float(duration)
            if values["duration"] < self.duration:   # a shorter run: what it reaches
                values["schedule"] = self.schedule.within(values["duration"], self.duration)
        if imu_rate is not None:
            values["imu_rate"] = float(imu_rate)
        config = ScenarioConfig(**values)
        config.validate(labels)
        return config

    def sensor_specs(self) -> dict[str, Any]:
        """Every sensor the scenario carries besides its IMU, section -> spec: the gimbal
        encoders always, then the GNSS receiver, the odometer and ``sensors`` (the
        order their faults are recorded in)."""
        specs: dict[str, Any] = {"encoder": self.encoder}
        if self.gps is not None:
            specs["gps"] = self.gps
        if self.odometer is not None:
            specs["odometer"] = self.odometer
        specs.update(self.sensors)
        return specs

    def sensor_suite(self) -> SensorSuite:
        """The scenario's sensors besides its IMU (``sensor_specs``), to measure with,
        under the schedule."""
        return SensorSuite.of(self.sensor_specs(), self.schedule)

    @property
    def imu_interval(self) -> float:
        """IMU sample interval, s."""
        return 1.0 / self.imu_rate

    @property
    def imu_samples(self) -> int:
        """Number of IMU intervals in the run."""
        return int(round(self.duration * self.imu_rate))

    def validate(self, labels: dict[str, str] | None = None) -> None:
        """One-line ConfigError naming the first bad value by its key as the file writes
        it (``run.duration_s``), or by labels[field] where an option set it."""
        labels = labels or {}
        _check_range(_key("origin", "latitude"), self.latitude / deg, -89.0, 89.0, "deg")
        _check_range(_key("origin", "longitude"), self.longitude / deg, -180.0, 360.0, "deg")
        _check_range(_key("origin", "height"), self.height, -500.0, 10000.0, "m")
        duration = labels.get("duration") or _key("run", "duration")
        rate = labels.get("imu_rate") or _key("run", "imu_rate")
        _check_range(duration, self.duration, 0.0, 86400.0, "s", low_open=True)
        _check_range(rate, self.imu_rate, 0.0, 2000.0, "Hz", low_open=True)
        if abs(self.duration * self.imu_rate - self.imu_samples) > 1e-6 or self.imu_samples < 2:
            raise ConfigError(f"{duration} = {self.duration:g} s must be a whole number (>= 2)"
                              f" of IMU intervals of {self.imu_interval:g} s")
        try:
            self.faults.check(self.duration)
            self.schedule.check(self.duration)
        except ValueError as exc:
            raise ConfigError(_as_written(str(exc))) from None
        try:
            carrier = world_named(self.world)
        except ValueError as exc:              # a world registered once, no longer
            raise ConfigError(str(exc)) from None
        for sensor in self.sensor_suite().sensors:
            if not sensor.needs <= carrier.gives:
                able = sorted(n for n, w in WORLDS.items() if sensor.needs <= w.gives)
                raise ConfigError(f"[{sensor.section}]: the {self.world} world cannot carry "
                                  f"it (only {', '.join(able)}); remove the table")
            try:
                sensor.check(self.duration, self.imu_rate, self.world)
            except ValueError as exc:
                raise ConfigError(_written_in(str(exc), sensor.section,
                                              sensor_units(sensor.section))) from None
        if self.gps is not None and not carrier.dynamic:
            ratio = self.imu_rate / self.gps.rate
            if abs(ratio - round(ratio)) > 1e-9:
                raise ConfigError(f"gps.rate_hz = {self.gps.rate:g} Hz must divide {rate} "
                                  f"= {self.imu_rate:g} Hz")
        if carrier.dynamic:
            physics = carrier.physics_rate
            ratio = physics / self.imu_rate
            if abs(ratio - round(ratio)) > 1e-9:
                raise ConfigError(f"{rate} = {self.imu_rate:g} Hz must divide the "
                                  f"{self.world} physics rate {physics:g} Hz")
        try:
            carrier.check(self)
        except ValueError as exc:
            raise ConfigError(_as_written(str(exc))) from None


def scenario_path(name_or_path: str) -> Path:
    """The TOML file of a shipped scenario's name, or the given .toml path; a one-line
    ConfigError for an unknown name or a missing file."""
    path = Path(name_or_path)
    if path.suffix == ".toml":
        if not path.is_file():
            raise ConfigError(f"scenario file {name_or_path} does not exist")
        return path
    if name_or_path not in scenario_names():
        raise ConfigError(f"unknown scenario {name_or_path!r}; valid choices: "
                          + ", ".join(scenario_names()))
    return DATA_DIR / f"{name_or_path}.toml"


def load_scenario(name_or_path: str) -> ScenarioConfig:
    """Load a shipped scenario by name, or a TOML file by path."""
    path = scenario_path(name_or_path)
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    return _build(raw, str(path))


def _build(raw: dict[str, Any], source: str) -> ScenarioConfig:
    plugged = [name for name in sensor_types() if name not in SECTIONS]
    tables = [*SECTIONS, *plugged]
    unknown = sorted(set(raw) - set(tables) - set(TOP_KEYS) - {"schedule"})
    if unknown:
        close = difflib.get_close_matches(unknown[0], [*tables, *TOP_KEYS], n=1,
                                          cutoff=0.6)
        hint = ("" if not close else f"; did you mean [{close[0]}]?"
                if close[0] in tables else f"; did you mean {close[0]}?")
        raise ConfigError(f"{source}: {unknown[0]!r} is neither a key ("
                          + ", ".join(TOP_KEYS) + ") nor a table ([" + "], [".join(tables)
                          + "])" + hint)
    for key in TOP_KEYS:
        if key in raw and not isinstance(raw[key], str):
            raise ConfigError(f"{source}: {key} must be a string, got {raw[key]!r}")
    def section(name: str, required: bool = True,
                units: dict[str, str] = UNITS) -> dict[str, Any]:
        if name not in raw:
            if required:
                raise ConfigError(f"{source}: missing table [{name}]")
            return {}
        if not isinstance(raw[name], dict):
            raise ConfigError(f"{source}: [{name}] must be a table")
        return _to_si(raw[name], name, units)

    if "world" not in raw:
        raise ConfigError(f"{source}: missing key world; valid choices: "
                          + ", ".join(sorted(WORLDS)))
    world = raw["world"]
    if world not in WORLDS:
        raise _unknown_choice("world", world, WORLDS)
    carrier = world_named(world)
    motion_units = {**UNITS, **carrier.units} if carrier.units else UNITS
    motion = section("motion", units=motion_units)
    origin, run, imu = (section(s) for s in ("origin", "run", "imu"))
    for name, table, keys in (("origin", origin, ("latitude", "longitude", "height")),
                              ("run", run, ("duration", "imu_rate"))):
        valid = [k + UNITS[k] for k in keys]
        for key in table:
            if key not in keys:
                written = key + UNITS.get(key, "")   # as the file wrote it
                raise _not_a_parameter(f"{name}.{written}", written, valid)
        for key in keys:
            if key not in table:
                raise ConfigError(f"{source}: missing key {_key(name, key)}")
    bias_frame = imu.pop("bias_frame", "sensor")
    if bias_frame not in BIAS_FRAMES:
        raise _unknown_choice("imu.bias_frame", bias_frame, BIAS_FRAMES)
    preset, imu_spec = _imu_spec(imu)
    if not carrier.carries_indexer and "indexer" in raw:
        raise ConfigError(f"[indexer]: the {world} world carries no indexer; remove the "
                          "table")
    indexer = section("indexer", False)
    if indexer:
        motion["indexer"] = _indexer(indexer)
    try:
        fields_, random_phase = carrier.motion_fields(motion)
    except UnknownMotionKey as exc:
        written = exc.name + motion_units.get(exc.name, "")
        raise _not_a_parameter(f"motion.{written}", written, exc.valid, exc.what) from None
    except ValueError as exc:
        raise ConfigError(_as_written(str(exc))) from None
    motion_obj = _dataclass_from(carrier.motion_type, fields_, "motion", motion_units)
    encoder = _dataclass_from(GimbalEncoderSpec, section("encoder", False), "encoder")
    odometer = (_sensor(section("odometer"), ODOMETER_PRESETS, OdometerSpec, "odometer")
                if "odometer" in raw else None)
    gps = _sensor(section("gps"), GPS_PRESETS, GpsSpec, "gps") if "gps" in raw else None
    sensors = tuple((name, _plugged_sensor(raw, name, source)) for name in plugged
                    if name in raw)
    present = {"gps": gps, "odometer": odometer, "encoder": encoder, **dict(sensors)}
    schedule = _schedule(raw.get("schedule", []), source,
                         {k: v for k, v in present.items() if v is not None}, imu_spec,
                         carrier, motion_obj, motion_units)
    filter_table = tuple(sorted(section("filter", False).items()))
    if "gimbal_stalls" in motion:
        raise ConfigError("motion.gimbal_stalls: stalls are faults; write them in [faults] "
                          "(gimbal_stalls = [[start_s, duration_s]])")
    faults = _dataclass_from(ImuFaults, section("faults", False), "faults")
    if faults.gimbal_stalls:
        if not getattr(motion_obj, "has_gimbal", False):
            raise ConfigError(f"faults.gimbal_stalls: the {world} scenario {source} has no "
                              "gimbal (gimbal rates or an [indexer]) to stall")
        motion_obj = replace(motion_obj, gimbal_stalls=faults.gimbal_stalls)
    try:
        config = ScenarioConfig(
            name=str(raw.get("name", Path(source).stem)), paper=str(raw.get("paper", "")),
            experiment=_experiment_key(raw.get("experiment", "")), source=source,
            world=world, latitude=origin["latitude"], longitude=origin["longitude"],
            height=origin["height"], duration=run["duration"], imu_rate=run["imu_rate"],
            imu_preset=preset, imu=imu_spec, imu_bias_frame=bias_frame,
            encoder=encoder, motion=motion_obj,
            random_linear_phase=random_phase, odometer=odometer, gps=gps,
            sensors=sensors, schedule=schedule, filter=filter_table, faults=faults)
    except KeyError as exc:
        raise ConfigError(f"{source}: missing key {exc.args[0]}") from None
    config.validate()
    return config
