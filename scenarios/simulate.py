"""One episode of a scenario: its world's truth (``scenarios.worlds``), the IMU's ideal or
erroneous increments with their faults, and every other sensor's record
(``sensors.suite``)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aligngym.models.earth import TangentPlane
from aligngym.models.truth import NavigationTruth
from aligngym.scenarios.config import ConfigError, ScenarioConfig
from aligngym.scenarios.truth_cache import remember_code
from aligngym.scenarios.worlds import world_of
from aligngym.sensors.base import FaultLog, SensorRecord, SensorTruth
from aligngym.sensors.imu import ImuRealization, apply_imu_errors

remember_code()   # the code this process simulates with labels its truth-cache entries


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
            arrays = record.arrays() if record is not None else {}
            clash = sorted(set(arrays) & set(out))
            if clash:
                raise ValueError(f"{type(record).__name__}'s array {clash[0]!r} has the "
                                 "name of another array of the episode; give the record "
                                 "a PREFIX")
            out.update(arrays)
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


BYTES_PER_IMU_SAMPLE = 2200
"""Peak memory of a simulation per IMU sample (truth, increments, sensor errors;
measured: 2.2 kB on the prescribed ship at 100 Hz)."""
BYTES_PER_PHYSICS_STEP = 500
"""And per MuJoCo step of the dynamic worlds (the recorded states; measured 0.2-0.5 kB)."""
MEMORY_SHARE = 0.5
"""A simulation may use at most this share of the memory available when it starts."""


def memory_estimate(config: ScenarioConfig) -> float:
    """Bytes a simulation of config needs at its peak (an upper estimate)."""
    steps = config.duration * (world_of(config).physics_rate or 0.0)
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
    rngs = episode_rngs(seed)
    shared = world_of(config).truth(config, rngs, seed)
    truth = shared.truth
    dtheta, dv = shared.dtheta.copy(), shared.dv.copy()   # the cached arrays stay as they are
    dtheta, dv, realization = _imu_errors(config, rngs, dtheta, dv, ideal,
                                          truth.gimbal_angles)
    imu_t, dtheta, dv, imu_faults = _faults(config, shared.imu_t, dtheta, dv)
    seen = SensorTruth(truth=truth, plane=TangentPlane(config.latitude, config.longitude,
                                                       config.height),
                       antenna=shared.antenna, rear_wheels=shared.rear_wheels,
                       has_gimbal=config.motion.has_gimbal)
    suite = config.sensor_suite()
    records = suite.measure(seen, rngs.__getitem__, ideal)
    return Episode(config=config, seed=seed, ideal=ideal, truth=truth, imu_t=imu_t,
                   dtheta=dtheta, dv=dv, imu_realization=realization, measurements=records,
                   faults=_fault_log(config, imu_faults, suite.faults(records,
                                                                      config.duration)),
                   cross_track=shared.cross_track)


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
    from aligngym.models.gimbal import STALL_CATCH_UP
    rows = list(imu_rows)
    rows += [("gimbal_stall", start, start + (1.0 + STALL_CATCH_UP) * duration)
             for start, duration in config.faults.gimbal_stalls]
    rows += sensor_rows
    if not rows:
        return None
    kind, start, end = zip(*rows)
    return FaultLog(kind=np.array(kind, dtype=str), start=np.array(start, dtype=float),
                    end=np.array(end, dtype=float))


def _imu_errors(config, rngs, dtheta, dv, ideal, gimbal_angles):
    """Erroneous increments and the drawn realization (None when ideal). With
    ``imu.bias_frame = "hull"`` the constant biases are constant in the hull frame:
    C_b^s at each interval's middle (from the true gimbal angles (M+1, 2)) rotates them."""
    if ideal:
        return dtheta, dv, None
    realization = config.imu.draw(rngs["imu_realization"])
    rotation = None
    if config.imu_bias_frame == "hull":
        from aligngym.models.gimbal import gimbal_C_s_b
        mid = 0.5 * (gimbal_angles[:-1] + gimbal_angles[1:])
        rotation = np.swapaxes(gimbal_C_s_b(mid), -1, -2)
    dtheta, dv = apply_imu_errors(dtheta, dv, config.imu_interval, config.imu, realization,
                                  rngs["imu_noise"], rotation, _white_noise(config,
                                                                            dtheta.shape[0]))
    return dtheta, dv, realization


def _white_noise(config: ScenarioConfig, intervals: int
                 ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The gyro's and the accelerometer's white-noise density (rad/sqrt(s), m/s/sqrt(s))
    per IMU interval, at its middle, where the schedule changes it (a vibration burst);
    None where it does not."""
    t = (np.arange(intervals) + 0.5) * config.imu_interval
    out = []
    for triad in ("gyro", "accel"):
        name = f"{triad}.white_noise_density"
        out.append(config.schedule.profile("imu", name, getattr(config.imu, triad)
                                           .white_noise_density, t)
                   if config.schedule.touches("imu", name) else None)
    return out[0], out[1]
