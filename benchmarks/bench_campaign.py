"""Benchmark: wall time of the full paper-003 campaign (50 episodes, 4 filters, two
starting errors) on this machine, split into episode preparation and the filters.
Run: python benchmarks/bench_campaign.py [EPISODES] [SCENARIO]
(SCENARIO: ship-sway-rotary by default, or ship-waves-rotary)."""
from __future__ import annotations

import os
import sys
import time

from scenarios.paper003 import Paper003Experiment, prepare_episode, run_campaign


def main() -> None:
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    scenario = sys.argv[2] if len(sys.argv) > 2 else "ship-sway-rotary"
    experiment = Paper003Experiment(scenario=scenario)
    start = time.perf_counter()
    prepare_episode(experiment, 12345)
    one = time.perf_counter() - start
    start = time.perf_counter()
    result = run_campaign(episodes=episodes, seed=0, progress=False, experiment=experiment)
    total = time.perf_counter() - start
    filters = sum(r.result.seconds_per_epoch * (r.result.t.size - 1) for r in result.runs)
    print(f"paper003 campaign on {scenario}, {episodes} episodes x 4 filters x 2 starts, "
          f"{os.cpu_count()} cores: {total:.1f} s wall")
    print(f"  one episode (720 s MuJoCo truth + IMU + integrals + coarse): {one:.2f} s on one "
          f"core; filters (all runs, batched): {filters:.1f} s; the rest is preparation "
          f"in parallel, metrics and process start-up")
    for r in result.runs[:: 2]:
        print(f"  {r.filter:6s} {r.result.seconds_per_epoch * 1e3:.2f} ms per epoch for "
              f"{len(result.seeds)} episodes")


if __name__ == "__main__":
    main()
