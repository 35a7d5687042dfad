"""Benchmark: wall time to simulate a 600 s ship-sway-rotary episode with its IMU (the
strapdown's cost: bench_strapdown.py), with the truth computed (cold: the on-disk truth
cache off, ALIGNGYM_TRUTH_CACHE=off; and the first run into a fresh, empty cache
directory, which also stores the entry) and read from the truth cache (warm: the
same fresh directory; what a second run of a scenario costs); and MuJoCo's sensor pass
over the truth's 120001 states two ways: the former per-state Python loop over the seven
sensor-path calls, and the kinematic twin's one ``mujoco.rollout`` call
(``models.world``), with their largest difference. The per-process truth cache is
cleared before every run. Run: python benchmarks/bench_simulate.py"""
from __future__ import annotations

import os
import tempfile
import time

import mujoco
import numpy as np

from aligngym.models.world import ROLLOUT_THREADS
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.simulate import simulate
from aligngym.scenarios.world_truth import TRUTH_OVERSAMPLING, prescribed_world_truth
from aligngym.scenarios.worlds import make_world
from aligngym.scenarios.truth_cache import TRUTH_CACHE_ENV


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


def with_cache(setting: str, fn):
    """fn() with ALIGNGYM_TRUTH_CACHE set to setting ("off" or a directory), restored
    after."""
    old = os.environ.get(TRUTH_CACHE_ENV)
    os.environ[TRUTH_CACHE_ENV] = setting
    try:
        return fn()
    finally:
        if old is None:
            os.environ.pop(TRUTH_CACHE_ENV, None)
        else:
            os.environ[TRUTH_CACHE_ENV] = old


def main() -> None:
    config = load_scenario("ship-sway-rotary")

    def episode():
        prescribed_world_truth.cache_clear()            # the truth is cached per process too
        simulate(config, seed=1)

    def timed():
        start = time.perf_counter()
        episode()
        return time.perf_counter() - start

    cold = with_cache("off", lambda: best_of(episode))
    with tempfile.TemporaryDirectory(prefix="aligngym-truth-") as folder:
        storing = with_cache(folder, timed)          # empty directory: compute and store
        warm = with_cache(folder, lambda: best_of(episode))
    world = make_world(config, np.random.default_rng(0))
    n = config.imu_samples * TRUTH_OVERSAMPLING
    t = np.arange(n + 1) * (config.duration / n)
    loop = best_of(lambda: python_loop(world, t))
    batched = best_of(lambda: world.sample(t))
    reference = python_loop(world, t)
    samples = world.sample(t)
    gyro = world._adr["imu_gyro"][0]
    print("simulate ship-sway-rotary 600 s, 100 Hz IMU with errors (best of 3):")
    for label, wall in (("cold, truth cache off", cold),
                        ("cold, first run into a fresh cache (once)", storing),
                        ("warm, truth read from the cache", warm)):
        print(f"  {label + ':':43s}{wall:6.2f} s wall ({600 / wall:5.0f}x real time)")
    print(f"MuJoCo sensor pass, {t.size} states: per-state Python loop {loop:.2f} s, "
          f"kinematic rollout ({ROLLOUT_THREADS} threads) {batched:.2f} s; largest gyro "
          f"difference {np.abs(samples.omega_ts_s - reference[:, gyro:gyro + 3]).max():.1e}"
          " rad/s")


if __name__ == "__main__":
    main()
