"""Benchmark: wall time of a paper's full campaign (its default filters and starts) on
this machine, split into episode preparation and the filters.
Run: python benchmarks/bench_campaign.py [EPISODES] [SCENARIO]
(SCENARIO: ship-sway-rotary by default (paper 003), ship-waves-rotary, figure8-gps
(paper 001), static-large-azimuth (paper 002), ring-road-odometer (paper 000) or
usv-mems-swing (paper 004, moderate swing))."""
from __future__ import annotations

import os
import sys
import time

from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.experiments import experiment_for


def main() -> None:
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    scenario = sys.argv[2] if len(sys.argv) > 2 else "ship-sway-rotary"
    experiment = experiment_for(scenario)
    start = time.perf_counter()
    experiment.prepare_episode(12345)
    one = time.perf_counter() - start
    start = time.perf_counter()
    result = run_campaign(experiment, episodes=episodes, seed=0, progress=False)
    total = time.perf_counter() - start
    filters = sum(r.result.seconds_per_epoch * (r.result.t.size - 1) for r in result.runs)
    print(f"paper{experiment.paper} campaign on {scenario}, {episodes} episodes x "
          f"{len(experiment.default_filters)} filters x {len(experiment.starts)} start(s), "
          f"{os.cpu_count()} cores: {total:.1f} s wall")
    print(f"  one episode ({experiment.duration:g} s of simulation, sensors and the "
          f"filter-independent stages): {one:.2f} s on one core (numba compilation "
          f"included); filters (all runs, batched): {filters:.1f} s; the rest is "
          f"preparation in parallel, metrics and process start-up")
    for name in dict.fromkeys(r.filter for r in result.runs):
        seconds = sum(r.result.seconds_per_epoch for r in result.runs if r.filter == name)
        print(f"  {name:6s} {seconds * 1e3:.2f} ms per epoch for {len(result.seeds)} "
              f"episodes from {len(experiment.starts)} start(s), one batch")


if __name__ == "__main__":
    main()
