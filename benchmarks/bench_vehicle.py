"""Benchmark: simulate 600 s of each vehicle scenario with all its sensors (x real time
on one core), and the odometer's effective scale factor (odometer distance over the
truth path length, minus one). Run: python benchmarks/bench_vehicle.py"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.simulate import simulate


def main() -> None:
    for name in ("ring-road-odometer", "figure8-gps"):
        config = load_scenario(name).with_options(duration=600.0)
        config = replace(config, motion=replace(config.motion, start_time=5.0))
        start = time.perf_counter()
        episode = simulate(config, seed=1)
        wall = time.perf_counter() - start
        line = f"{name}: 600 s in {wall:.1f} s wall = {600 / wall:.0f}x real time"
        if "odometer" in episode.measurements:
            speed = np.linalg.norm(episode.truth.v_n[:, :2], axis=1)
            path = np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(episode.truth.t))
            scale = episode.measurements["odometer"].distance[-1] / path - 1.0
            dk = float(episode.measurements["odometer"].scale_error)
            line += (f"; odometer effective scale {scale * 1e3:+.2f} ppt (configured dK_D "
                     f"{dk * 1e3:+.2f} ppt, tyre slip/radius {(scale - dk) * 1e3:+.2f} ppt)")
        print(line)


if __name__ == "__main__":
    main()
