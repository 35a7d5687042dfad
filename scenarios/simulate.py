"""One episode of a scenario: MuJoCo truth, ideal or erroneous IMU increments, encoders."""
from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from aligngym.models.earth import TangentPlane
from aligngym.models.platform import StaticPlatformWorld
from aligngym.models.ship import ShipWorld
from aligngym.models.truth import NavigationTruth, imu_truth
from aligngym.models.world import PrescribedWorld
from aligngym.scenarios.config import PHYSICS_RATE, ConfigError, ScenarioConfig
from aligngym.scenarios.truth_cache import cached_arrays, remember_code
from aligngym.sensors.base import FaultLog, SensorRecord, SensorTruth
from aligngym.sensors.imu import ImuRealization, apply_imu_errors, ideal_increments

remember_code()   # the code this process simulates with labels its truth-cache entries

# Truth is sampled at twice the IMU rate so that Simpson's rule integrates the increments.
TRUTH_OVERSAMPLING = 2


@dataclass(frozen=True)
class Episode:
    """One simulated run. truth: at the IMU interval boundaries (M+1 samples);
    imu_t (M,) s; dtheta (M, 3) rad, dv (M, 3) m/s in the sensor frame;
    imu_realization: the drawn errors (None when ideal); measurements: every other
    sensor's typed record by its section ("encoder" always; "odometer", "gps", "dvl"
    and a user's sensors where the scenario has their tables); faults: the faults
    injected (None without any); cross_track: the car's cross-track error at the
    boundaries, m (None for other worlds). The truth (and the arrays taken from it, such
    as imu_t and the odometer's t) may be shared with other episodes of the same motion:
    read-only; copy it to modify it."""

    config: ScenarioConfig
    seed: int
    ideal: bool
    truth: NavigationTruth
    imu_t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    imu_realization: ImuRealization | None
    measurements: dict[str, SensorRecord] = field(default_factory=dict)
    faults: FaultLog | None = None
    cross_track: np.ndarray | None = None

    @property
    def gimbal_encoder(self) -> np.ndarray:
        """The gimbal encoders' readings (M+1, 2) rad (outer, inner)."""
        return self.measurements["encoder"].angles

    def arrays(self) -> dict[str, np.ndarray]:
        """The export arrays (README "Data files")."""
        tr = self.truth
        out = {"t": tr.t, "lat": tr.lat, "lon": tr.lon, "h": tr.h, "v_n": tr.v_n,
               "q_b_n": tr.q_b_n, "q_s_n": tr.q_s_n, "gimbal_angles": tr.gimbal_angles,
               "imu_t": self.imu_t, "dtheta": self.dtheta, "dv": self.dv,
               "scenario": np.array(self.config.name), "seed": np.array(self.seed),
               "ideal": np.array(self.ideal)}
        if self.imu_realization is not None:
            out["gyro_bias"] = self.imu_realization.gyro.bias
            out["accel_bias"] = self.imu_realization.accel.bias
        if self.cross_track is not None:
            out["cross_track"] = self.cross_track
        for record in (*self.measurements.values(), self.faults):
            out.update(record.arrays() if record is not None else {})
        return out

    def save(self, path: str | Path) -> Path:
        """Write the arrays to an .npz file (no pickled objects), atomically."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ConfigError(f"--out must name a .npz file, got {str(path)!r}")
        path.parent.mkdir(parents=True, exist_ok=True)
        from aligngym.scenarios.atomic import atomic_path
        with atomic_path(path) as tmp:        # a killed run leaves no partial file
            np.savez(tmp, **self.arrays())
        return path


def episode_rngs(seed: int) -> dict[str, np.random.Generator]:
    """Independent random streams of one episode, so that the truth does not depend on
    whether sensor errors are drawn."""
    children = np.random.SeedSequence(seed).spawn(6)
    return _Streams(seed, {name: np.random.default_rng(s) for name, s in
                           zip(("motion", "imu_realization", "imu_noise", "encoder",
                                "odometer", "gps"), children)})


class _Streams(dict):
    """An episode's random streams by name: the six above, and for any other name (a
    sensor's: "dvl", a user's) a stream of its own from the seed and the name."""

    def __init__(self, seed: int, streams: dict[str, np.random.Generator]) -> None:
        super().__init__(streams)
        self.seed = seed

    def __missing__(self, name: str) -> np.random.Generator:
        import zlib
        stream = np.random.default_rng(np.random.SeedSequence(
            self.seed, spawn_key=(6, zlib.crc32(name.encode()))))
        self[name] = stream
        return stream


def make_world(config: ScenarioConfig, rng: np.random.Generator) -> PrescribedWorld:
    """The scenario's prescribed MuJoCo world (the ship with this episode's random motion
    phases, or the static platform)."""
    if config.world == "static-platform":
        return StaticPlatformWorld(config.motion)
    if config.world != "ship-prescribed":
        raise ConfigError(f"world = {config.world!r} is unknown; valid choices: "
                          "ship-prescribed, static-platform")
    return ShipWorld(episode_motion(config, rng))


def make_dynamic_world(config: ScenarioConfig, rngs: dict[str, np.random.Generator],
                       pictures: bool = False):
    """The scenario's dynamic MuJoCo world (the car with its road, or the wave-driven
    ship with its sea), drawn from the episode's random streams (``episode_rngs``);
    pictures: the car dressed to be drawn, its body and track (visual only: the same
    motion)."""
    motion = config.motion
    if config.world == "car":
        from aligngym.models.car import CarWorld
        return CarWorld(motion.car_params(), motion.make_track(), motion.profile(),
                        roughness_seed=int(rngs["motion"].integers(2 ** 31)),
                        pictures=pictures)
    if config.world == "ship-waves":
        from aligngym.models.waves import WaveShipWorld
        return WaveShipWorld(motion, rngs["motion"])
    raise ConfigError(f"world = {config.world!r} is not a dynamic world (car, ship-waves)")


def run_gimbal(run, motion):
    """The gimbal's motion (``GimbalMotion``) of a dynamic world's run: the one MuJoCo
    simulated (an indexer's servo), else the motion's constant rates, with their stalls;
    None without a gimbal."""
    if run.gimbal is not None:
        return run.gimbal
    return motion.gimbal_state if motion.has_gimbal else None


def episode_motion(config: ScenarioConfig, rng: np.random.Generator):
    """The prescribed ship's motion of one episode (its random linear phases drawn)."""
    motion = config.motion
    if config.random_linear_phase:
        motion = replace(motion, linear_phase=tuple(rng.uniform(0.0, 2 * np.pi, 3)))
    return motion


BYTES_PER_IMU_SAMPLE = 2200
"""Peak memory of a simulation per IMU sample (truth, increments, sensor errors;
measured: 2.2 kB on the prescribed ship at 100 Hz)."""
BYTES_PER_PHYSICS_STEP = 500
"""And per MuJoCo step of the dynamic worlds (the recorded states; measured 0.2-0.5 kB)."""
MEMORY_SHARE = 0.5
"""A simulation may use at most this share of the memory available when it starts."""


def memory_estimate(config: ScenarioConfig) -> float:
    """Bytes a simulation of config needs at its peak (an upper estimate)."""
    steps = config.duration * PHYSICS_RATE.get(config.world, 0.0)
    return config.imu_samples * BYTES_PER_IMU_SAMPLE + steps * BYTES_PER_PHYSICS_STEP


def available_memory() -> float | None:
    """Bytes of memory available now (Linux: MemAvailable), None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(config: ScenarioConfig) -> None:
    """One-line ConfigError, before any work, for a run that would need more than
    MEMORY_SHARE of the available memory (naming the fields that set its size)."""
    need, have = memory_estimate(config), available_memory()
    if have is not None and need > MEMORY_SHARE * have:
        raise ConfigError(f"run.duration_s = {config.duration:g} s at run.imu_rate_hz = "
                          f"{config.imu_rate:g} needs about {need / 1e9:.1f} GB to simulate, "
                          f"more than {MEMORY_SHARE:.0%} of the {have / 1e9:.1f} GB available; "
                          "shorten the run or lower the IMU rate")


def simulate(config: ScenarioConfig, seed: int = 0, ideal: bool = False) -> Episode:
    """Simulate one episode of the scenario (refused first if it would not fit in
    memory: ``check_memory``)."""
    if seed < 0:
        raise ConfigError(f"seed = {seed} must be >= 0")
    check_memory(config)
    if config.world in ("car", "ship-waves"):
        return _simulate_dynamic(config, seed, ideal)
    rngs = episode_rngs(seed)
    where = (config.latitude, config.longitude, config.height, config.duration,
             config.imu_samples)
    if config.world == "static-platform":  # the same truth for every seed: computed once
        truth, imu_t, dtheta, dv, antenna = _static_truth(config.motion, *where)
    else:
        truth, imu_t, dtheta, dv, antenna = _ship_truth(episode_motion(config, rngs["motion"]),
                                                        *where)
    dtheta, dv = dtheta.copy(), dv.copy()   # the cached arrays stay as they are
    dtheta, dv, realization = _imu_errors(config, rngs, dtheta, dv, ideal,
                                          truth.gimbal_angles)
    imu_t, dtheta, dv, imu_faults = _faults(config, imu_t, dtheta, dv)
    fixes = None
    if config.gps is not None:
        every = np.arange(0, truth.t.size, int(round(config.imu_rate / config.gps.rate)))
        fixes = (truth.t[every], antenna[0][every], antenna[1][every])
    seen = SensorTruth(truth=truth, plane=_plane(config), antenna=fixes,
                       has_gimbal=config.motion.has_gimbal)
    return _episode(config, seed, ideal, truth, imu_t, dtheta, dv, realization, imu_faults,
                    seen, rngs)


def _plane(config: ScenarioConfig) -> TangentPlane:
    return TangentPlane(config.latitude, config.longitude, config.height)


def _episode(config, seed, ideal, truth, imu_t, dtheta, dv, realization, imu_faults,
             seen: SensorTruth, rngs, cross_track=None) -> Episode:
    """The episode, its sensors measured (``sensors.suite``) and its faults recorded."""
    suite = config.sensor_suite()
    records = suite.measure(seen, rngs.__getitem__, ideal)
    return Episode(config=config, seed=seed, ideal=ideal, truth=truth, imu_t=imu_t,
                   dtheta=dtheta, dv=dv, imu_realization=realization, measurements=records,
                   faults=_fault_log(config, imu_faults, suite.faults(records,
                                                                      config.duration)),
                   cross_track=cross_track)


def imu_rails(config: ScenarioConfig) -> tuple[float, float]:
    """Full scales (gyro rad/s, accelerometer m/s^2) of the scenario's IMU: where a
    saturated axis sticks (``sensors.faults``)."""
    from aligngym.sensors.faults import ACCEL_FULL_SCALE, GYRO_FULL_SCALE, full_scale
    return (full_scale(config.imu.gyro.measurement_range, GYRO_FULL_SCALE),
            full_scale(config.imu.accel.measurement_range, ACCEL_FULL_SCALE))


def _faults(config: ScenarioConfig, imu_t, dtheta, dv):
    """The scenario's [faults] injected into the increments: imu_t, dtheta, dv and the
    record rows (kind, start s, end s) of the IMU faults."""
    if not config.faults.any:
        return imu_t, dtheta, dv, []
    imu_t, dtheta, dv, record = config.faults.apply(imu_t, dtheta, dv, config.imu_interval,
                                                    *imu_rails(config))
    return imu_t, dtheta, dv, list(zip(record["fault_kind"], record["fault_start"],
                                       record["fault_end"]))


def _fault_log(config: ScenarioConfig, imu_rows: list, sensor_rows: list
               ) -> FaultLog | None:
    """The record of every fault (None without any): the IMU faults' rows, the gimbal
    stalls (to the end of their catch-up), then the sensors' (GNSS outages and outliers
    at the stamp of the fix each is put on, odometer slips, DVL dropouts)."""
    from aligngym.models.world import STALL_CATCH_UP
    rows = list(imu_rows)
    rows += [("gimbal_stall", start, start + (1.0 + STALL_CATCH_UP) * duration)
             for start, duration in config.faults.gimbal_stalls]
    rows += sensor_rows
    if not rows:
        return None
    kind, start, end = zip(*rows)
    return FaultLog(kind=np.array(kind, dtype=str), start=np.array(start, dtype=float),
                    end=np.array(end, dtype=float))


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


@lru_cache(maxsize=2)
def _ship_truth(motion, latitude: float, longitude: float, height: float, duration: float,
                imu_samples: int):
    """``_prescribed_truth`` of the prescribed ship, cached per process by its motion (a
    scenario without random phases has one truth for every seed) and on disk
    (``truth_cache``); read-only arrays."""
    key = (motion, latitude, longitude, height, duration, imu_samples)
    return _prescribed_cached("ship-prescribed", key, lambda: _prescribed_truth(
        ShipWorld(motion), latitude, longitude, height, duration, imu_samples))


@lru_cache(maxsize=4)
def _static_truth(motion, latitude: float, longitude: float, height: float,
                  duration: float, imu_samples: int):
    """``_prescribed_truth`` of the static platform, cached per process (its truth does
    not depend on the episode) and on disk; read-only arrays."""
    key = (motion, latitude, longitude, height, duration, imu_samples)
    return _prescribed_cached("static-platform", key, lambda: _prescribed_truth(
        StaticPlatformWorld(motion), latitude, longitude, height, duration, imu_samples))


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


def _imu_errors(config, rngs, dtheta, dv, ideal, gimbal_angles):
    """Erroneous increments and the drawn realization (None when ideal). With
    ``imu.bias_frame = "hull"`` the constant biases are constant in the hull frame:
    C_b^s at each interval's middle (from the true gimbal angles (M+1, 2)) rotates them."""
    if ideal:
        return dtheta, dv, None
    realization = config.imu.draw(rngs["imu_realization"])
    rotation = None
    if config.imu_bias_frame == "hull":
        from aligngym.models.world import gimbal_C_s_b
        mid = 0.5 * (gimbal_angles[:-1] + gimbal_angles[1:])
        rotation = np.swapaxes(gimbal_C_s_b(mid), -1, -2)
    dtheta, dv = apply_imu_errors(dtheta, dv, config.imu_interval, config.imu, realization,
                                  rngs["imu_noise"], rotation)
    return dtheta, dv, realization


@dataclass(frozen=True)
class _DynamicMotion:
    """What a dynamic world's run gives its episodes (every seed alike on a smooth road,
    one seed on a rough road or a random sea): the truth at the IMU interval
    boundaries, the ideal increments of the IMU case (N, 3), the cross-track error at the
    boundaries (or None), the rear wheels' angles there (N+1, 2, rad; None without wheels)
    and the GNSS antenna's (t, position, velocity) at the fixes (or None)."""

    truth: NavigationTruth
    dtheta: np.ndarray
    dv: np.ndarray
    cross_track: np.ndarray | None
    rear_wheels: np.ndarray | None
    antenna: tuple[np.ndarray, np.ndarray, np.ndarray] | None


def _dynamic_motion(config: ScenarioConfig, rngs: dict[str, np.random.Generator]
                    ) -> _DynamicMotion:
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
    return _DynamicMotion(truth=truth, dtheta=dtheta, dv=dv, cross_track=cross_track,
                          rear_wheels=wheels, antenna=antenna)


SMOOTH_ROAD_RUNS = 4
"""Smooth-road car runs kept per process (``_smooth_road_motion``): 12.6 MB each for
600 s at 100 Hz."""
_smooth_road_runs: OrderedDict[tuple, _DynamicMotion] = OrderedDict()


def _motion_key(config: ScenarioConfig, any_duration: bool = False) -> tuple:
    """Everything a dynamic world's run (``_dynamic_motion``) reads of config but the
    episode's random streams (any_duration: "any" in place of the duration)."""
    odo, gps = config.odometer, config.gps
    return (config.world, config.motion, config.latitude, config.longitude, config.height,
            "any" if any_duration else config.duration, config.imu_rate,
            None if odo is None else (odo.mounting_pitch, odo.mounting_heading),
            None if gps is None else gps.rate)


def _cached_motion(kind: str, key: tuple, compute, usable=None) -> _DynamicMotion:
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
    return _DynamicMotion(truth=_truth_from(a), dtheta=a["dtheta"], dv=a["dv"],
                          cross_track=a.get("cross_track"), rear_wheels=a.get("rear_wheels"),
                          antenna=antenna)


def _prefix(shared: _DynamicMotion, config: ScenarioConfig) -> _DynamicMotion:
    """The first config.duration of a longer run: the run of that duration bit for bit
    (MuJoCo steps and the driver do not look ahead, and the IMU and truth pipeline works
    sample by sample)."""
    m = config.imu_samples
    if shared.dtheta.shape[0] == m:
        return shared
    cut = slice(0, m + 1)
    antenna = shared.antenna
    if antenna is not None:      # the fixes at the physics steps the shorter run makes
        dt = 1.0 / PHYSICS_RATE["car"]
        last = np.arange(int(round(config.duration / dt)) + 1)[-1:] * dt
        antenna = tuple(a[: int(np.searchsorted(antenna[0], last[0], "right"))]
                        for a in antenna)
    return _DynamicMotion(truth=shared.truth.take(cut), dtheta=shared.dtheta[:m],
                          dv=shared.dv[:m], antenna=antenna,
                          cross_track=None if shared.cross_track is None
                          else shared.cross_track[cut],
                          rear_wheels=None if shared.rear_wheels is None
                          else shared.rear_wheels[cut])


def _smooth_road_motion(config: ScenarioConfig, rngs: dict[str, np.random.Generator]
                        ) -> _DynamicMotion:
    """``_dynamic_motion`` of the car on a smooth road, cached per process and on disk
    (``truth_cache``): with no road heightfield the run does not depend on the episode,
    so every seed, ideal or not, has the same truth, and a shorter run is the start of a
    longer one (``_prefix``): one run per motion, the longest asked for. Its arrays are
    read-only, so a caller that would modify them fails instead of changing the next
    episode."""
    key = _motion_key(config, any_duration=True)
    m = config.imu_samples
    held = _smooth_road_runs.get(key)
    if held is None or held.dtheta.shape[0] < m:
        held = _cached_motion("car-smooth-road", key, lambda: _dynamic_motion(config, rngs),
                              usable=lambda arrays: arrays["dtheta"].shape[0] >= m)
        _smooth_road_runs[key] = held
    _smooth_road_runs.move_to_end(key)
    while len(_smooth_road_runs) > SMOOTH_ROAD_RUNS:
        _smooth_road_runs.popitem(last=False)
    return _prefix(held, config)


def _simulate_dynamic(config: ScenarioConfig, seed: int, ideal: bool) -> Episode:
    """A dynamic world (the car, the ship in waves; both at 500 Hz): MuJoCo's discrete
    steps, the exact discrete IMU, and the world's odometer, GPS and encoders."""
    rngs = episode_rngs(seed)
    motion = config.motion
    if config.world == "car" and motion.roughness_rms == 0.0:
        shared = _smooth_road_motion(config, rngs)
    else:   # the road's heightfield or the sea is drawn from the seed's motion stream
        shared = _cached_motion(f"{config.world}-seeded", (*_motion_key(config), int(seed)),
                                lambda: _dynamic_motion(config, rngs))
    truth = shared.truth
    dtheta, dv, realization = _imu_errors(config, rngs, shared.dtheta.copy(),
                                          shared.dv.copy(), ideal, truth.gimbal_angles)
    imu_t, dtheta, dv, imu_faults = _faults(config, truth.t[1:], dtheta, dv)
    seen = SensorTruth(truth=truth, plane=_plane(config), antenna=shared.antenna,
                       rear_wheels=shared.rear_wheels, has_gimbal=motion.has_gimbal)
    return _episode(config, seed, ideal, truth, imu_t, dtheta, dv, realization, imu_faults,
                    seen, rngs, cross_track=shared.cross_track)
