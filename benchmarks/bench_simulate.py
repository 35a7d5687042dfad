"""Benchmark: wall time to simulate a 600 s ship-sway-rotary episode with its IMU, and the
strapdown's cost per IMU step. Run: python benchmarks/bench_simulate.py"""
from __future__ import annotations

import time

import numpy as np

from estimators.strapdown import StrapdownState, run_strapdown
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
    episode = simulate(config.with_options(duration=60.0), seed=1, ideal=True)
    tr = episode.truth
    for batch in (1, 50):
        init = StrapdownState.from_arrays(np.tile(tr.q_s_n[0], (batch, 1)),
                                          np.tile(tr.v_n[0], (batch, 1)),
                                          np.full(batch, tr.lat[0]), np.full(batch, tr.lon[0]),
                                          np.full(batch, tr.h[0]))
        dth = np.broadcast_to(episode.dtheta, (batch,) + episode.dtheta.shape)
        dv = np.broadcast_to(episode.dv, (batch,) + episode.dv.shape)
        sec = best_of(lambda: run_strapdown(init, dth, dv, config.imu_interval), repeat=1)
        steps = episode.dtheta.shape[0]
        print(f"strapdown batch {batch:3d}: {sec / steps * 1e6:.0f} us per IMU step "
              f"({sec / steps / batch * 1e6:.1f} us per episode-step)")


if __name__ == "__main__":
    main()
