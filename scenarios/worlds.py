"""The carrier worlds a scenario file names (``world = "..."``): each a registered role
that parses and checks its [motion] table, builds its MuJoCo world, and gives an episode
its truth (``WorldTruth``: the navigation truth at the IMU interval boundaries, the ideal
increments of the IMU, what the sensors see of the carrier), through the truth cache.
Prescribed worlds (the swaying ship, the static platform) are sampled at
TRUTH_OVERSAMPLING x the IMU rate; dynamic ones (the car, the ship in waves) are MuJoCo's
discrete steps at their physics rate. A new world is one class registered with
``register_world`` plus its scenario files."""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections import OrderedDict
from dataclasses import dataclass, replace
from functools import lru_cache
import math
from typing import Any, ClassVar

import numpy as np

from aligngym.models.earth import TangentPlane
from aligngym.models.truth import NavigationTruth, imu_truth
from aligngym.models.units import deg
from aligngym.models.world import PrescribedWorld
from aligngym.scenarios.truth_cache import cached_arrays
from aligngym.sensors.imu import ideal_increments

Scenario = Any
"""A ``scenarios.config.ScenarioConfig`` (that module imports this one)."""

TRUTH_OVERSAMPLING = 2
"""Prescribed worlds' truth is sampled at twice the IMU rate, so that Simpson's rule
integrates the increments."""


@dataclass(frozen=True)
class WorldTruth:
    """What a world's run gives an episode (arrays may be shared by episodes: read-only):
    truth at the IMU interval boundaries (M+1 samples); imu_t (M,) s, the intervals' end
    times; dtheta, dv (M, 3) the ideal increments of the IMU case (rad, m/s); antenna: the
    GNSS antenna's (t (G,) s, position (G, 3) m, velocity (G, 3) m/s in the plane) at the
    fixes of the scenario's receiver, or None; rear_wheels: the car's driven wheels'
    angles (M+1, 2) rad, or None; cross_track: the car's distance from its track (M+1,) m,
    or None."""

    truth: NavigationTruth
    imu_t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    antenna: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    rear_wheels: np.ndarray | None = None
    cross_track: np.ndarray | None = None


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
        raise ValueError(f"{field} = {value:g} {unit} is out of range {bracket}{low:g}, "
                         f"{high:g}]")


class World(ABC):
    """A carrier world. Class attributes: ``name`` (the scenario file's ``world`` key);
    ``motion_type`` (its [motion] dataclass); ``units`` (the unit suffixes of its own
    [motion] keys, beside the file's ``config.UNITS``); ``physics_rate`` (Hz, MuJoCo's fixed rate of
    a dynamic world, which the IMU rate must divide; None for a prescribed world);
    ``carries_indexer`` (an [indexer] table may turn its IMU); ``has_antenna`` (a GNSS
    antenna on the carrier); ``view`` (the renderer's follow camera: distance m,
    elevation deg, azimuth deg, close-up size m; ``camera`` may size it to the motion);
    ``close_up_groups`` (MuJoCo geom groups the renderer's close-up shows; None: all);
    ``look_between`` (the follow camera looks between the carrier's origin and the IMU,
    a large hull's, rather than at the IMU)."""

    name: ClassVar[str]
    motion_type: ClassVar[type]
    units: ClassVar[dict[str, str]] = {}
    physics_rate: ClassVar[float | None] = None
    carries_indexer: ClassVar[bool] = False
    has_antenna: ClassVar[bool] = True
    view: ClassVar[tuple[float, float, float, float]] = (10.0, -20.0, 40.0, 1.0)
    close_up_groups: ClassVar[tuple[int, ...] | None] = None
    look_between: ClassVar[bool] = False

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


WORLDS: dict[str, type[World]] = {}
"""Registered worlds by their scenario-file name (``register_world``)."""


def register_world(cls: type[World]) -> type[World]:
    """Register a world class under its name (a class decorator)."""
    name = getattr(cls, "name", "")
    if not (isinstance(name, str) and name):
        raise ValueError(f"world {cls.__name__} must have a name")
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


def run_gimbal(run, motion):
    """The gimbal's motion (``GimbalMotion``) of a dynamic world's run: the one MuJoCo
    simulated (an indexer's servo), else the motion's constant rates, with their stalls;
    None without a gimbal."""
    if run.gimbal is not None:
        return run.gimbal
    return motion.gimbal_state if motion.has_gimbal else None


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
        truth, imu_t, dtheta, dv, (r, v) = _prescribed_world_truth(
            self.name, motion, config.latitude, config.longitude, config.height,
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
    carries_indexer = True
    look_between = True

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

    def camera(self, config):
        length = max(config.motion.hull_size)
        gimbal = max(0.6 * min(1.0, config.motion.hull_size[0] / 18.0), 0.03 * length)
        return (1.15 * length, -15.0, 30.0, 3.2 * gimbal)

    def episode_motion(self, config, rng):
        motion = config.motion
        if config.random_linear_phase:
            motion = replace(motion, linear_phase=tuple(rng.uniform(0.0, 2 * np.pi, 3)))
        return motion

    def scene(self, motion):
        from aligngym.models.ship import ShipWorld
        return ShipWorld(motion)


@register_world
class StaticPlatform(Prescribed):
    """A level slab at a constant attitude (paper 002's static base); no antenna."""

    name = "static-platform"
    has_antenna = False
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


@lru_cache(maxsize=4)
def _prescribed_world_truth(world: str, motion, latitude: float, longitude: float,
                            height: float, duration: float, imu_samples: int):
    """``_prescribed_truth`` of a prescribed world's motion, cached per process by its
    motion (a motion without random phases has one truth for every seed) and on disk
    (``truth_cache``, kind: the world's name); read-only arrays."""
    key = (motion, latitude, longitude, height, duration, imu_samples)
    return _prescribed_cached(world, key, lambda: _prescribed_truth(
        world_named(world).scene(motion), latitude, longitude, height, duration,
        imu_samples))


def _prescribed_truth(world: PrescribedWorld, latitude: float, longitude: float,
                      height: float, duration: float, imu_samples: int):
    """Truth at the IMU interval boundaries, the ideal increments (imu_t, dtheta, dv) and
    the GNSS antenna's plane position and velocity at the boundaries ((M+1, 3) each, or
    None) of a prescribed world whose plane origin is at latitude, longitude (rad),
    height (m), over duration (s) in imu_samples intervals; MuJoCo is sampled at
    TRUTH_OVERSAMPLING x the IMU rate."""
    plane = TangentPlane(latitude, longitude, height)
    n_fine = imu_samples * TRUTH_OVERSAMPLING
    t_fine = np.arange(n_fine + 1) * (duration / n_fine)
    samples = world.sample(t_fine)
    truth, omega_is_s, f_s = imu_truth(samples, plane, TRUTH_OVERSAMPLING)
    imu_t, dtheta, dv = ideal_increments(t_fine, omega_is_s, f_s, TRUTH_OVERSAMPLING)
    every = slice(None, None, TRUTH_OVERSAMPLING)
    antenna = ((samples.antenna_r_t[every], samples.antenna_v_t[every])
               if samples.antenna_r_t is not None else (None, None))
    return truth, imu_t, dtheta, dv, antenna


def _prescribed_cached(kind: str, key: tuple, compute):
    """A prescribed world's (truth, imu_t, dtheta, dv, (antenna r, v)) through the truth
    cache, its arrays made read-only."""
    def arrays():
        truth, imu_t, dtheta, dv, (r, v) = compute()
        out = _truth_arrays(truth) | {"imu_t": imu_t, "dtheta": dtheta, "dv": dv}
        return out | ({} if r is None else {"antenna_r": r, "antenna_v": v})
    a = _read_only(cached_arrays(kind, key, arrays))
    return (_truth_from(a), a["imu_t"], a["dtheta"], a["dv"],
            (a.get("antenna_r"), a.get("antenna_v")))


def _truth_arrays(truth: NavigationTruth) -> dict[str, np.ndarray]:
    return {f"truth.{name}": value for name, value in vars(truth).items()
            if value is not None}


def _truth_from(arrays: dict[str, np.ndarray]) -> NavigationTruth:
    return NavigationTruth(**{name[6:]: value for name, value in arrays.items()
                              if name.startswith("truth.")})


def _read_only(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """arrays with each made read-only (shared between episodes: nobody may modify them)."""
    for value in arrays.values():
        value.setflags(write=False)
    return arrays


# --- dynamic worlds ------------------------------------------------------------------------
class Dynamic(World):
    """A world MuJoCo integrates at its physics rate (its run recorded at every step)."""

    physics_rate = 500.0

    def motion_fields(self, table):
        return dict(table), False

    shared_kind: ClassVar[str] = "{name}-shared"
    """The truth-cache kind of a run every seed shares (``shared_by_seeds``)."""

    def check(self, config):
        config.motion.check()

    def shared_by_seeds(self, config: Scenario) -> bool:
        """Every seed has the same run (nothing in it is drawn from the seed)."""
        return False

    def truth(self, config, rngs, seed):
        if self.shared_by_seeds(config):
            return _shared_motion(self.shared_kind.format(name=self.name), config, rngs)
        return _cached_motion(f"{self.name}-seeded", (*_motion_key(config), int(seed)),
                              lambda: _dynamic_motion(config, rngs))


@register_world
class CarOnRoad(Dynamic):
    """The car driven around its track by a pure-pursuit driver; a rough road's
    heightfield is drawn from the episode's motion stream."""

    name = "car"
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
    carries_indexer = True
    look_between = True
    camera = SwayingShip.camera

    @property
    def motion_type(self):
        from aligngym.models.waves import WaveShipMotion
        return WaveShipMotion

    def build(self, config, rngs, pictures=False):
        from aligngym.models.waves import WaveShipWorld
        return WaveShipWorld(config.motion, rngs["motion"])


def _dynamic_motion(config: Scenario, rngs: dict[str, np.random.Generator]
                    ) -> WorldTruth:
    """A dynamic world's run from the episode's motion stream: MuJoCo's discrete steps and
    the exact discrete IMU of the case (on its gimbal, turned by the odometer's mounting)."""
    from aligngym.models.attitude import euler_to_quat, quat_mul, quat_to_dcm
    from aligngym.models.truth import gravity_t, plane_truth
    from aligngym.models.world import SmoothRun

    motion = config.motion
    world = make_dynamic_world(config, rngs)
    run = world.run(config.duration)
    if world.smooth_truth:
        run = SmoothRun(run)
    plane = TangentPlane(config.latitude, config.longitude, config.height)
    site, v_site = run.imu_trajectory()
    gimbal_motion = run_gimbal(run, motion)
    dtheta, dv = run.imu_increments(plane.omega_ie_t,
                                    gravity_t(plane, 0.5 * (site[:-1] + site[1:])),
                                    gimbal_motion)
    gimbal = (np.zeros((run.t.size, 2)) if gimbal_motion is None
              else gimbal_motion(run.t)[0])
    # C_s_b = Rz(outer) Rx(inner): the PSINS Euler DCM with pitch = inner, yaw = outer.
    q_s_b = euler_to_quat(np.stack([gimbal[:, 1], np.zeros(run.t.size), gimbal[:, 0]], -1))
    k = int(round(1.0 / (config.imu_rate * run.dt)))
    m = config.imu_samples
    dtheta = dtheta[: m * k].reshape(m, k, 3).sum(1)
    dv = dv[: m * k].reshape(m, k, 3).sum(1)
    if config.odometer is not None:
        # The IMU case sits on the chassis (on the gimbal, if any) turned by the odometer's
        # mounting angles: C_s^b = C_gimbal Rz(heading) Rx(pitch), so the error a filter
        # must absorb is in the data. Constant: the increments turn with it exactly.
        odo = config.odometer
        q_mount = euler_to_quat(np.array([odo.mounting_pitch, 0.0, odo.mounting_heading]))
        q_s_b = quat_mul(q_s_b, q_mount)
        C_mount = quat_to_dcm(q_mount)
        dtheta, dv = dtheta @ C_mount, dv @ C_mount
    q_s_t = quat_mul(run.quat, q_s_b)
    idx = np.arange(m + 1) * k
    truth = plane_truth(plane, run.t[idx], site[idx], v_site[idx], run.quat[idx],
                        q_s_t[idx], gimbal[idx])
    antenna = None
    if config.gps is not None:
        g_idx = np.arange(0, run.t.size, int(round(1.0 / (config.gps.rate * run.dt))))
        antenna = (run.t[g_idx], *run.point_kinematics(motion.gps_antenna_b, g_idx))
    cross_track = None if run.cross_track is None else run.cross_track[idx]
    wheels = None if run.wheel_angles is None else run.wheel_angles[idx][:, 2:4]
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=dtheta, dv=dv,
                      cross_track=cross_track, rear_wheels=wheels, antenna=antenna)


SHARED_RUNS = 4
"""Runs every seed shares kept per process (``_shared_motion``): 12.6 MB each for a
600 s smooth-road car run at 100 Hz."""
_shared_runs: OrderedDict[tuple, WorldTruth] = OrderedDict()


def _motion_key(config: Scenario, any_duration: bool = False) -> tuple:
    """Everything a dynamic world's run (``_dynamic_motion``) reads of config but the
    episode's random streams (any_duration: "any" in place of the duration)."""
    odo, gps = config.odometer, config.gps
    return (config.world, config.motion, config.latitude, config.longitude, config.height,
            "any" if any_duration else config.duration, config.imu_rate,
            None if odo is None else (odo.mounting_pitch, odo.mounting_heading),
            None if gps is None else gps.rate)


def _cached_motion(kind: str, key: tuple, compute, usable=None) -> WorldTruth:
    """A dynamic world's run through the truth cache, its arrays made read-only (usable:
    ``truth_cache.cached_arrays``'s)."""
    def arrays():
        shared = compute()
        out = _truth_arrays(shared.truth) | {"dtheta": shared.dtheta, "dv": shared.dv}
        for name in ("cross_track", "rear_wheels"):
            if getattr(shared, name) is not None:
                out[name] = getattr(shared, name)
        if shared.antenna is not None:
            out.update(zip(("antenna_t", "antenna_r", "antenna_v"), shared.antenna))
        return out
    a = _read_only(cached_arrays(kind, key, arrays, usable))
    antenna = ((a["antenna_t"], a["antenna_r"], a["antenna_v"]) if "antenna_t" in a
               else None)
    truth = _truth_from(a)
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=a["dtheta"], dv=a["dv"],
                      cross_track=a.get("cross_track"), rear_wheels=a.get("rear_wheels"),
                      antenna=antenna)


def _prefix(shared: WorldTruth, config: Scenario) -> WorldTruth:
    """The first config.duration of a longer run: the run of that duration bit for bit
    (MuJoCo steps and the driver do not look ahead, and the IMU and truth pipeline works
    sample by sample)."""
    m = config.imu_samples
    if shared.dtheta.shape[0] == m:
        return shared
    cut = slice(0, m + 1)
    antenna = shared.antenna
    if antenna is not None:      # the fixes at the physics steps the shorter run makes
        dt = 1.0 / world_of(config).physics_rate
        last = np.arange(int(round(config.duration / dt)) + 1)[-1:] * dt
        antenna = tuple(a[: int(np.searchsorted(antenna[0], last[0], "right"))]
                        for a in antenna)
    truth = shared.truth.take(cut)
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=shared.dtheta[:m],
                      dv=shared.dv[:m], antenna=antenna,
                      cross_track=None if shared.cross_track is None
                      else shared.cross_track[cut],
                      rear_wheels=None if shared.rear_wheels is None
                      else shared.rear_wheels[cut])


def _shared_motion(kind: str, config: Scenario, rngs: dict[str, np.random.Generator]
                   ) -> WorldTruth:
    """``_dynamic_motion`` of a run every seed shares (the car on a smooth road: with no
    road heightfield the run does not depend on the episode, so every seed, ideal or not,
    has the same truth), cached per process and on disk (``truth_cache``, kind), and a
    shorter run is the start of a longer one (``_prefix``): one run per motion, the
    longest asked for. Its arrays are read-only, so a caller that would modify them
    fails instead of changing the next episode."""
    key = _motion_key(config, any_duration=True)
    m = config.imu_samples
    held = _shared_runs.get(key)
    if held is None or held.dtheta.shape[0] < m:
        held = _cached_motion(kind, key, lambda: _dynamic_motion(config, rngs),
                              usable=lambda arrays: arrays["dtheta"].shape[0] >= m)
        _shared_runs[key] = held
    _shared_runs.move_to_end(key)
    while len(_shared_runs) > SHARED_RUNS:
        _shared_runs.popitem(last=False)
    return _prefix(held, config)
