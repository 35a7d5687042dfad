"""The carrier worlds a scenario file names (``world = "..."``): each a registered role
that parses and checks its [motion] table, builds its MuJoCo world, and gives an episode
its truth (``WorldTruth``: the navigation truth at the IMU interval boundaries, the ideal
increments of the IMU, what the sensors see of the carrier), through the truth cache.
Prescribed worlds (the swaying ship, the static platform) are sampled at
TRUTH_OVERSAMPLING x the IMU rate; dynamic ones (the car, the ship in waves) are MuJoCo's
discrete steps at their physics rate. A new world is one class registered with
``register_world`` plus its scenario files. How a run becomes the truth:
``scenarios.world_truth``."""
from __future__ import annotations

import hashlib
import inspect
import math
import sys
from abc import ABC, abstractmethod
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from aligngym.models.ship import HULL_SIZE_RANGE
from aligngym.models.units import deg
from aligngym.models.world import PrescribedWorld
from aligngym.scenarios.truth_cache import in_truth_sources
from aligngym.scenarios.world_truth import (Scenario, WorldTruth, cached_motion,
                                            dynamic_motion, motion_key,
                                            prescribed_world_truth, run_gimbal,
                                            shared_motion)
from aligngym.sensors.base import same_class

__all__ = ["World", "WorldTruth", "WORLDS", "register_world", "world_named", "world_of",
           "make_world", "make_dynamic_world", "run_gimbal", "check_range",
           "UnknownMotionKey"]


class UnknownMotionKey(ValueError):
    """A [motion] key the world does not take: its name (unit suffix stripped), the
    valid keys as a file writes them, and what it is not a parameter of."""

    def __init__(self, name: str, valid: list[str], what: str = "") -> None:
        self.name, self.valid, self.what = name, valid, what
        super().__init__(f"motion.{name} is not a parameter{what}")


def check_range(field: str, value: float, low: float, high: float, unit: str,
                low_open: bool = False) -> None:
    """ValueError "field = value unit is out of range [low, high]" unless value is in it."""
    ok = math.isfinite(value) and (value > low if low_open else value >= low) and value <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise ValueError(f"{field} = {value:g}{' ' * bool(unit)}{unit} is out of range {bracket}{low:g}, "
                         f"{high:g}]")


class World(ABC):
    """A carrier world. Class attributes: ``name`` (the scenario file's ``world`` key);
    ``motion_type`` (its [motion] dataclass); ``units`` (the unit suffixes of its own
    [motion] keys, beside the file's ``config.UNITS``); ``physics_rate`` (Hz, MuJoCo's fixed rate of
    a dynamic world, which the IMU rate must divide; None for a prescribed world);
    ``carries_indexer`` (an [indexer] table may turn its IMU); ``gives`` (what its
    carrier gives the sensors that need it, ``sensors.base.Sensor.needs``: "antenna",
    "wheels", "hull"); ``view`` (the renderer's follow camera: distance m,
    elevation deg, azimuth deg, close-up size m; ``camera`` may size it to the motion);
    ``close_up_groups`` (MuJoCo geom groups the renderer's close-up shows; None: all);
    ``look_between`` (the follow camera looks between the carrier's origin and the IMU,
    a large hull's, rather than at the IMU); ``schedulable`` (the [motion] fields a
    [[schedule]] entry may change within the episode, e.g. the sea state).

    What a world of your own must give: a ``motion_type`` that is a frozen (hashable)
    dataclass with the gimbal's fields (``models.gimbal.GimbalRates``: its rates, stalls
    and ``has_gimbal``), in SI; a prescribed world's ``scene(motion)``, a
    ``models.world.PrescribedWorld`` whose MJCF has the body ``carrier``, the site ``imu``
    with ``IMU_SENSORS_MJCF`` and, for GNSS, an antenna site, and whose ``sample(t)`` gives
    the motion at every time (``StaticPlatformWorld`` samples once and repeats it: right
    for a still world only); a dynamic world's ``build`` an object whose ``run(duration)``
    returns a ``models.discrete_run.DiscreteRun``. Its truth is cached under a kind that carries
    a hash of its module's source (``cache_kind``)."""

    name: ClassVar[str]
    motion_type: ClassVar[type]
    units: ClassVar[dict[str, str]] = {}
    physics_rate: ClassVar[float | None] = None
    carries_indexer: ClassVar[bool] = False
    gives: ClassVar[frozenset[str]] = frozenset()
    view: ClassVar[tuple[float, float, float, float]] = (10.0, -20.0, 40.0, 1.0)
    close_up_groups: ClassVar[tuple[int, ...] | None] = None
    look_between: ClassVar[bool] = False
    schedulable: ClassVar[tuple[str, ...]] = ()

    def motion_fields(self, table: dict[str, Any]) -> tuple[dict[str, Any], bool]:
        """The [motion] table (SI, unit suffixes stripped) as motion_type's fields, and
        whether each episode draws its own random phases; ValueError names the field."""
        return dict(table), False

    def check(self, config: Scenario) -> None:
        """ValueError naming ``motion.field_unit`` where the motion cannot be run."""

    def camera(self, config: Scenario) -> tuple[float, float, float, float]:
        """The renderer's follow camera and close-up for this scenario (``view``)."""
        return self.view

    @abstractmethod
    def build(self, config: Scenario, rngs: dict[str, np.random.Generator],
              pictures: bool = False):
        """The MuJoCo world of one episode (drawn from its random streams); pictures: dressed
        to be drawn (visual only: the same motion)."""

    @abstractmethod
    def truth(self, config: Scenario, rngs: dict[str, np.random.Generator],
              seed: int) -> WorldTruth:
        """The episode's truth (``WorldTruth``), through the truth cache."""

    @property
    def dynamic(self) -> bool:
        """MuJoCo integrates its motion (True), or it is prescribed and sampled."""
        return self.physics_rate is not None

    @classmethod
    def cache_kind(cls, kind: str) -> str:
        """The truth-cache kind of this world's runs: ``kind`` for a world whose module is in
        the cache's code hash (``truth_cache.TRUTH_SOURCES``: the shipped worlds), with a
        hash of the defining module's source for any other (a user's, or one the package
        defines elsewhere, in an experiment say), so that editing it never serves its old
        truth."""
        module = sys.modules.get(cls.__module__)
        if module is None or in_truth_sources(getattr(module, "__file__", None)):
            return kind
        try:
            source = inspect.getsource(module)
        except (OSError, TypeError):           # no source to read: never cached alike
            source = f"{cls.__module__}.{cls.__qualname__} {id(cls)}"
        return f"{kind}-{hashlib.sha256(source.encode()).hexdigest()[:16]}"


WORLDS: dict[str, type[World]] = {}
"""Registered worlds by their scenario-file name (``register_world``)."""


def register_world(cls: type[World]) -> type[World]:
    """Register a world class under its name (a class decorator); a name another class
    holds is refused (the same class again, e.g. its module reloaded, replaces itself)."""
    name = getattr(cls, "name", "")
    if not (isinstance(name, str) and name):
        raise ValueError(f"world {cls.__name__} must have a name")
    held = WORLDS.get(name)
    if held is not None and not same_class(held, cls):
        raise ValueError(f"world name {name!r} is taken by {held.__module__}."
                         f"{held.__qualname__}")
    WORLDS[name] = cls
    return cls


def world_named(name: str) -> World:
    """The registered world of that name (ValueError listing the valid names)."""
    if name not in WORLDS:
        raise ValueError(f"world = {name!r} is unknown; valid choices: "
                         + ", ".join(sorted(WORLDS)))
    return WORLDS[name]()


def world_of(config: Scenario) -> World:
    """The scenario's world."""
    return world_named(config.world)


def make_world(config: Scenario, rng: np.random.Generator) -> PrescribedWorld:
    """The scenario's prescribed MuJoCo world (rng: the episode's motion stream)."""
    return world_of(config).build(config, {"motion": rng})


def make_dynamic_world(config: Scenario, rngs: dict[str, np.random.Generator],
                       pictures: bool = False):
    """The scenario's dynamic MuJoCo world, drawn from the episode's random streams."""
    world = world_of(config)
    if not world.dynamic:
        raise ValueError(f"world = {config.world!r} is not a dynamic world ("
                         + ", ".join(n for n, w in WORLDS.items() if w.physics_rate) + ")")
    return world.build(config, rngs, pictures)


# --- prescribed worlds ---------------------------------------------------------------------
class Prescribed(World):
    """A world whose motion is a function of time (``models.world.PrescribedWorld``),
    sampled at TRUTH_OVERSAMPLING x the IMU rate."""

    def episode_motion(self, config: Scenario, rng: np.random.Generator):
        """The motion of one episode (rng: its motion stream); the scenario's by default."""
        return config.motion

    @abstractmethod
    def scene(self, motion) -> PrescribedWorld:
        """The MuJoCo world of a motion."""

    def build(self, config, rngs, pictures=False):
        return self.scene(self.episode_motion(config, rngs["motion"]))

    def truth(self, config, rngs, seed):
        motion = self.episode_motion(config, rngs["motion"])
        truth, imu_t, dtheta, dv, (r, v) = prescribed_world_truth(
            type(self), motion, config.latitude, config.longitude, config.height,
            config.duration, config.imu_samples)
        antenna = None
        if config.gps is not None and r is not None:
            every = np.arange(0, truth.t.size, int(round(config.imu_rate / config.gps.rate)))
            antenna = (truth.t[every], r[every], v[every])
        return WorldTruth(truth=truth, imu_t=imu_t, dtheta=dtheta, dv=dv, antenna=antenna)


@register_world
class SwayingShip(Prescribed):
    """The ship swaying in prescribed harmonics (paper 003's, the USV's), its IMU on a
    double-axis gimbal or an azimuth indexer; random linear phases per episode unless the
    file gives them."""

    name = "ship-prescribed"
    gives = frozenset({"antenna", "hull"})
    carries_indexer = True
    look_between = True
    schedulable = ("sway_scale",)

    @property
    def motion_type(self):
        from aligngym.models.ship import ShipSwayMotion
        return ShipSwayMotion

    def motion_fields(self, table):
        table = dict(table)
        phase = table.pop("linear_phase", "random")
        random_phase = phase == "random"
        if not random_phase:
            if not (isinstance(phase, tuple) and len(phase) == 3):
                raise ValueError("motion.linear_phase must be \"random\" or "
                                 "linear_phase_deg = [3 values]")
            table["linear_phase"] = phase
        for key in ("linear_amplitude", "linear_period", "linear_phase", "lever_arm_b"):
            if key in table and len(table[key]) != 3:
                raise ValueError(f"motion.{key} must have 3 values (E, N, U or R, F, U)")
        return table, random_phase

    def check(self, config):
        m = config.motion
        for name in ("yaw_period", "pitch_period", "roll_period"):
            check_range(f"motion.{name}_s", getattr(m, name), 0.0, 1e4, "s", low_open=True)
        for name in ("yaw_amplitude", "pitch_amplitude", "roll_amplitude"):
            check_range(f"motion.{name}_deg", getattr(m, name) / deg, 0.0, 45.0, "deg")
        for i, (a, p) in enumerate(zip(m.linear_amplitude, m.linear_period)):
            check_range(f"motion.linear_amplitude_m[{i}]", a, 0.0, 50.0, "m")
            check_range(f"motion.linear_period_s[{i}]", p, 0.0, 1e4, "s", low_open=True)
        for name in ("gimbal_outer_rate", "gimbal_inner_rate"):
            check_range(f"motion.{name}_deg_s", getattr(m, name) / deg, -360.0, 360.0,
                        "deg/s")
        check_range("motion.sway_scale", m.sway_scale, 0.0, 10.0, "")
        for i, size in enumerate(m.hull_size):      # the hull drawn (and the camera's reach)
            check_range(f"motion.hull_size_m[{i}]", size, *HULL_SIZE_RANGE, "m")
        for i, entry in enumerate(config.schedule.entries):
            value = dict(entry.values).get("sway_scale") if entry.section == "motion" else None
            if value is None:
                continue
            where = entry.label or f"schedule[{i}]"
            check_range(f"{where}.motion.sway_scale", value, 0.0, 10.0, "")
            if entry.ramp <= 0.0:
                raise ValueError(f"{where}.ramp_s = {entry.ramp:g} s must be > 0 for "
                                 "motion.sway_scale (a step would make the hull jump)")

    def camera(self, config):
        length = max(config.motion.hull_size)
        gimbal = max(0.6 * min(1.0, config.motion.hull_size[0] / 18.0), 0.03 * length)
        return (1.15 * length, -15.0, 30.0, 3.2 * gimbal)

    def episode_motion(self, config, rng):
        motion = config.motion
        if config.random_linear_phase:
            motion = replace(motion, linear_phase=tuple(rng.uniform(0.0, 2 * np.pi, 3)))
        changes = tuple(config.schedule.changes("motion", "sway_scale"))
        return replace(motion, sway_scale_changes=changes) if changes else motion

    def scene(self, motion):
        from aligngym.models.ship import ShipWorld
        return ShipWorld(motion)


@register_world
class StaticPlatform(Prescribed):
    """A level slab at a constant attitude (paper 002's static base); no antenna."""

    name = "static-platform"
    view = (2.8, -30.0, 135.0, 0.9)
    KEYS = {"yaw": "yaw_mean", "pitch": "pitch", "roll": "roll"}

    @property
    def motion_type(self):
        from aligngym.models.platform import StaticPlatformMotion
        return StaticPlatformMotion

    def motion_fields(self, table):
        unknown = sorted(set(table) - set(self.KEYS))
        if unknown:
            raise UnknownMotionKey(unknown[0], sorted(f"{key}_deg" for key in self.KEYS),
                                   " of the static platform")
        return {self.KEYS[key]: value for key, value in table.items()}, False

    def check(self, config):
        m = config.motion
        check_range("motion.yaw_deg", m.yaw_mean / deg, -360.0, 360.0, "deg")
        check_range("motion.pitch_deg", m.pitch / deg, -10.0, 10.0, "deg")
        check_range("motion.roll_deg", m.roll / deg, -10.0, 10.0, "deg")
        if m.has_gimbal:
            raise ValueError("motion: the static platform has no gimbal; gimbal rates must "
                             "be 0 deg/s")

    def scene(self, motion):
        from aligngym.models.platform import StaticPlatformWorld
        return StaticPlatformWorld(motion)


# --- dynamic worlds ------------------------------------------------------------------------
class Dynamic(World):
    """A world MuJoCo integrates at its physics rate (its run recorded at every step)."""

    physics_rate = 500.0
    shared_kind: ClassVar[str] = "{name}-shared"
    """The truth-cache kind of a run every seed shares (``shared_by_seeds``)."""

    def check(self, config):
        config.motion.check()

    def shared_by_seeds(self, config: Scenario) -> bool:
        """Every seed has the same run (nothing in it is drawn from the seed)."""
        return False

    def truth(self, config, rngs, seed):
        if self.shared_by_seeds(config):
            kind = self.cache_kind(self.shared_kind.format(name=self.name))
            return shared_motion(kind, config, lambda: self.build(config, rngs),
                                 1.0 / self.physics_rate)
        return cached_motion(self.cache_kind(f"{self.name}-seeded"),
                             (*motion_key(config), int(seed)),
                             lambda: dynamic_motion(config, self.build(config, rngs)))


@register_world
class CarOnRoad(Dynamic):
    """The car driven around its track by a pure-pursuit driver; a rough road's
    heightfield is drawn from the episode's motion stream."""

    name = "car"
    gives = frozenset({"antenna", "wheels"})
    shared_kind = "car-smooth-road"
    view = (10.0, -20.0, 40.0, 1.1)
    close_up_groups = (0, 0, 1, 0, 0, 0)     # the IMU sits inside the body: the instruments

    @property
    def motion_type(self):
        from aligngym.models.car import VehicleMotion
        return VehicleMotion

    def shared_by_seeds(self, config):
        return config.motion.roughness_rms == 0.0

    def build(self, config, rngs, pictures=False):
        from aligngym.models.car import CarWorld
        motion = config.motion
        return CarWorld(motion.car_params(), motion.make_track(), motion.profile(),
                        roughness_seed=int(rngs["motion"].integers(2 ** 31)),
                        pictures=pictures)


@register_world
class ShipInWaves(Dynamic):
    """The hull floating in a random sea drawn from the episode's motion stream."""

    name = "ship-waves"
    gives = frozenset({"antenna", "hull"})
    carries_indexer = True
    look_between = True
    camera = SwayingShip.camera

    @property
    def motion_type(self):
        from aligngym.models.waves import WaveShipMotion
        return WaveShipMotion

    schedulable = ("significant_wave_height",)

    def build(self, config, rngs, pictures=False):
        from aligngym.models.waves import WaveShipWorld
        sea_state = None
        if config.schedule.touches("motion", "significant_wave_height"):
            base = config.motion.significant_wave_height
            sea_state = lambda t: config.schedule.profile(  # noqa: E731
                "motion", "significant_wave_height", base, t)
        return WaveShipWorld(config.motion, rngs["motion"], sea_state=sea_state)
