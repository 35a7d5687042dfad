"""One episode of a scenario: MuJoCo truth, ideal or erroneous IMU increments, encoders."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from models.earth import TangentPlane
from models.ship import ShipWorld
from models.truth import NavigationTruth, navigation_truth
from scenarios.config import ConfigError, ScenarioConfig
from sensors.imu import ImuRealization, apply_imu_errors, ideal_increments

# Truth is sampled at twice the IMU rate so that Simpson's rule integrates the increments.
TRUTH_OVERSAMPLING = 2


@dataclass(frozen=True)
class Episode:
    """One simulated run. truth: at the IMU interval boundaries (M+1 samples);
    imu_t (M,) s; dtheta (M, 3) rad, dv (M, 3) m/s in the sensor frame;
    gimbal_encoder (M+1, 2) rad; imu_realization: the drawn errors (None when ideal)."""

    config: ScenarioConfig
    seed: int
    ideal: bool
    truth: NavigationTruth
    imu_t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    gimbal_encoder: np.ndarray
    imu_realization: ImuRealization | None

    def arrays(self) -> dict[str, np.ndarray]:
        """The export arrays (README "Data files")."""
        tr = self.truth
        out = {"t": tr.t, "lat": tr.lat, "lon": tr.lon, "h": tr.h, "v_n": tr.v_n,
               "q_b_n": tr.q_b_n, "q_s_n": tr.q_s_n, "gimbal_angles": tr.gimbal_angles,
               "imu_t": self.imu_t, "dtheta": self.dtheta, "dv": self.dv,
               "gimbal_encoder": self.gimbal_encoder,
               "scenario": np.array(self.config.name), "seed": np.array(self.seed),
               "ideal": np.array(self.ideal)}
        if self.imu_realization is not None:
            out["gyro_bias"] = self.imu_realization.gyro.bias
            out["accel_bias"] = self.imu_realization.accel.bias
        return out

    def save(self, path: str | Path) -> Path:
        """Write the arrays to an .npz file (no pickled objects)."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ConfigError(f"--out must name a .npz file, got {str(path)!r}")
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **self.arrays())
        return path


def episode_rngs(seed: int) -> dict[str, np.random.Generator]:
    """Independent random streams of one episode, so that the truth does not depend on
    whether sensor errors are drawn."""
    children = np.random.SeedSequence(seed).spawn(4)
    return {name: np.random.default_rng(s) for name, s in
            zip(("motion", "imu_realization", "imu_noise", "encoder"), children)}


def make_world(config: ScenarioConfig, rng: np.random.Generator) -> ShipWorld:
    """The scenario's MuJoCo world with this episode's random motion phases."""
    if config.world != "ship-prescribed":
        raise ConfigError(f"world = {config.world!r} is unknown; valid choices: ship-prescribed")
    motion = config.motion
    if config.random_linear_phase:
        motion = replace(motion, linear_phase=tuple(rng.uniform(0.0, 2 * np.pi, 3)))
    return ShipWorld(motion)


def simulate(config: ScenarioConfig, seed: int = 0, ideal: bool = False) -> Episode:
    """Simulate one episode of the scenario."""
    if seed < 0:
        raise ConfigError(f"seed = {seed} must be >= 0")
    rngs = episode_rngs(seed)
    world = make_world(config, rngs["motion"])
    plane = TangentPlane(config.latitude, config.longitude, config.height)
    n_fine = config.imu_samples * TRUTH_OVERSAMPLING
    t_fine = np.arange(n_fine + 1) * (config.duration / n_fine)
    truth_fine = navigation_truth(world.sample(t_fine), plane)
    imu_t, dtheta, dv = ideal_increments(truth_fine, TRUTH_OVERSAMPLING)
    realization = None
    if not ideal:
        realization = config.imu.draw(rngs["imu_realization"])
        dtheta, dv = apply_imu_errors(dtheta, dv, config.imu_interval, config.imu,
                                      realization, rngs["imu_noise"])
    truth = truth_fine.take(slice(None, None, TRUTH_OVERSAMPLING))
    encoder = config.encoder
    offsets = np.zeros(2) if ideal else encoder.draw_offsets(rngs["encoder"])
    reading = (truth.gimbal_angles.copy() if ideal
               else encoder.measure(truth.gimbal_angles, offsets))
    return Episode(config=config, seed=seed, ideal=ideal, truth=truth, imu_t=imu_t,
                   dtheta=dtheta, dv=dv, gimbal_encoder=reading, imu_realization=realization)
