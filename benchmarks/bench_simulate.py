"""Benchmark: wall time to simulate a 600 s ship-sway-rotary episode with its IMU (the
strapdown's cost: bench_strapdown.py), and MuJoCo's sensor pass over the truth's
120001 states two ways: the former per-state Python loop over the seven sensor-path
calls, and the kinematic twin's one ``mujoco.rollout`` call (``models.world``), with
their largest difference. Run: python benchmarks/bench_simulate.py"""
from __future__ import annotations

import time

import mujoco
import numpy as np

from aligngym.models.world import ROLLOUT_THREADS
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.simulate import TRUTH_OVERSAMPLING, _ship_truth, make_world, simulate


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def python_loop(world, t: np.ndarray) -> np.ndarray:
    """The former sensor pass: per state, MuJoCo's kinematics, velocity and acceleration
    passes and their sensors (the sensor path of mj_inverse)."""
    qpos, qvel, qacc = world.joint_state(t)
    m, d = world.model, world.data
    out = np.empty((t.size, m.nsensordata))
    for k in range(t.size):
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[k], qvel[k], qacc[k]
        for step in (mujoco.mj_kinematics, mujoco.mj_comPos, mujoco.mj_sensorPos,
                     mujoco.mj_comVel, mujoco.mj_sensorVel, mujoco.mj_rnePostConstraint,
                     mujoco.mj_sensorAcc):
            step(m, d)
        out[k] = d.sensordata
    return out


def main() -> None:
    config = load_scenario("ship-sway-rotary")

    def episode():
        _ship_truth.cache_clear()            # the truth is cached per process
        simulate(config, seed=1)

    total = best_of(episode)
    world = make_world(config, np.random.default_rng(0))
    n = config.imu_samples * TRUTH_OVERSAMPLING
    t = np.arange(n + 1) * (config.duration / n)
    loop = best_of(lambda: python_loop(world, t))
    batched = best_of(lambda: world.sample(t))
    reference = python_loop(world, t)
    samples = world.sample(t)
    gyro = world._adr["imu_gyro"][0]
    print(f"simulate ship-sway-rotary 600 s, 100 Hz IMU with errors: {total:.2f} s wall "
          f"({600 / total:.0f}x real time)")
    print(f"MuJoCo sensor pass, {t.size} states: per-state Python loop {loop:.2f} s, "
          f"kinematic rollout ({ROLLOUT_THREADS} threads) {batched:.2f} s; largest gyro "
          f"difference {np.abs(samples.omega_ts_s - reference[:, gyro:gyro + 3]).max():.1e}"
          " rad/s")


if __name__ == "__main__":
    main()
