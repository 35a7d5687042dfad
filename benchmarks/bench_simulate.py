"""Benchmark: wall time to simulate a 600 s ship-sway-rotary episode with its IMU (the
strapdown's cost: bench_strapdown.py). Run: python benchmarks/bench_simulate.py"""
from __future__ import annotations

import time

import numpy as np

from scenarios.config import load_scenario
from scenarios.simulate import TRUTH_OVERSAMPLING, make_world, simulate


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    config = load_scenario("ship-sway-rotary")
    total = best_of(lambda: simulate(config, seed=1))
    world = make_world(config, np.random.default_rng(0))
    n = config.imu_samples * TRUTH_OVERSAMPLING
    t = np.arange(n + 1) * (config.duration / n)
    mujoco_only = best_of(lambda: world.sample(t))
    print(f"simulate ship-sway-rotary 600 s, 100 Hz IMU with errors: {total:.2f} s wall "
          f"({600 / total:.0f}x real time); MuJoCo sampling alone ({t.size} states): "
          f"{mujoco_only:.2f} s")


if __name__ == "__main__":
    main()
