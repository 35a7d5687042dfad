"""Paper 001's paper setup: is each episode flagged `diverged` lost, or converged at the
floor its unmodelled gyro errors leave? (issue 42)

The paper setup's gyro has an uncalibrated misalignment (300") and scale factor (300
ppm) that the 15-state model does not hold. For each episode this runs every filter
twice from the same start: on the episode's own sensors, and on its twin, whose IMU has
those two errors alone (the same draws: the triads draw bias, scale factor and
misalignment in that order from the same stream) and whose GPS is error-free; the
twin's final error is the unmodelled floor. An episode whose error is its twin's,
within the filter's own few sigma, is converged at the floor; one far from it is not.

Run: python benchmarks/paper001_flags.py [--episodes N] [--seed S]
Prints per filter and episode: the status, the final error E/N/U and the twin's
(arcmin), the difference in the filter's sigma: docs/paper001.md's table.
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from aligngym.models.units import arcmin
from aligngym.scenarios.campaign import episode_seeds, run_filter
from aligngym.scenarios.experiments import experiment
from aligngym.sensors.imu import ImuSpec, TriadSpec


def unmodelled_only(spec: TriadSpec) -> TriadSpec:
    """The triad's scale factor and misalignment alone, drawn from the same stream."""
    return TriadSpec(bias_fixed=None if spec.bias_fixed is None else (0.0, 0.0, 0.0),
                     scale_factor_sigma=spec.scale_factor_sigma,
                     misalignment_sigma=spec.misalignment_sigma)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    exp = experiment("paper001", "paper")
    config = exp.scenario_config()
    twin_config = replace(
        config, imu=replace(config.imu, gyro=unmodelled_only(config.imu.gyro),
                            accel=TriadSpec()),   # drawn after the gyro: its draws kept
        gps=replace(config.gps, position_sigma_h=0.0, position_sigma_v=0.0,
                    velocity_sigma=0.0))
    seeds = episode_seeds(args.seed, args.episodes)
    real = [exp.prepare_episode(s) for s in seeds]
    twins = []
    for s, e in zip(seeds, real):
        t = exp.prepare_episode(s, twin_config)
        # the receiver's stated heading sigma, as on real data (the filters weigh it so)
        twins.append(replace(t, gps_heading_sigma=e.gps_heading_sigma))
    start = exp.start_errors(real)["coarse"]
    print("| filter | seed | status | final E / N / U (arcmin) | twin: the floor | "
          "(final - floor) / sigma E / N / U |")
    print("|---|---|---|---|---|---|")
    for name in exp.default_filters:
        on_real = run_filter(name, "coarse", start, real, exp)
        on_twin = run_filter(name, "coarse", start, twins, exp)
        for b, seed in enumerate(seeds):
            final = on_real.error_n[b, -1]
            floor = on_twin.error_n[b, -1]
            sigma = on_real.result.sigma_n[b, -1]
            print(f"| {name} | {seed} | {on_real.status[b]} | "
                  + " / ".join(f"{v / arcmin:+.1f}" for v in final) + " | "
                  + " / ".join(f"{v / arcmin:+.1f}" for v in floor) + " | "
                  + " / ".join(f"{v:+.1f}" for v in (final - floor) / sigma) + " |",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
