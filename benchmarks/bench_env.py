"""Benchmark: gymnasium env steps per second (1-s epochs, zero action), per estimator,
excluding reset (which simulates the episode). Run: python benchmarks/bench_env.py"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import aligngym  # noqa: F401  (registers the env ids)

SHIP_ID = "aligngym/ShipSwayRotary-v1"


def steps_per_second(estimator: str, steps: int = 599) -> tuple[float, float]:
    env = gym.make(SHIP_ID, estimator=estimator, episode_length=600.0)
    start = time.perf_counter()
    env.reset(seed=1)
    reset = time.perf_counter() - start
    zero = np.zeros(env.action_space.shape, np.float32)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(zero)
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate, reset


def main() -> None:
    for estimator in ("kf", "imakf", "ukf", "ckf", "sghkf-2", "sghkf-3"):
        rate, reset = steps_per_second(estimator)
        print(f"{estimator:8s} {rate:7.0f} steps/s   (reset incl. 720 s simulation: "
              f"{reset:.2f} s)")


if __name__ == "__main__":
    main()
