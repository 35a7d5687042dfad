"""aligngym simulate: one episode of a scenario, its data written (.npz)."""
from __future__ import annotations

import argparse
import time

from aligngym.scenarios.commands.options import float_option, option_labels, seed_option
from aligngym.scenarios.registry import scenario_names


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``simulate`` command's options."""
    sim = sub.add_parser("simulate", help="simulate one episode and write its data (.npz)")
    sim.add_argument("scenario", help="scenario name (" + ", ".join(scenario_names())
                     + ") or a .toml file")
    sim.add_argument("--duration", type=float_option("--duration"), metavar="S",
                     help="run length, s (default: the scenario's)")
    sim.add_argument("--seed", type=seed_option, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    sim.add_argument("--ideal", action="store_true", help="error-free sensors")
    sim.add_argument("--imu-rate", type=float_option("--imu-rate"), metavar="HZ",
                     help="IMU output rate, Hz (default: the scenario's)")
    sim.add_argument("--out", required=True, metavar="FILE.npz",
                     help="output file (arrays and units: README, Data files)")


def run(args: argparse.Namespace) -> int:
    from aligngym.models.attitude import quat_to_euler
    from aligngym.models.units import deg
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.simulate import simulate

    config = load_scenario(args.scenario).with_options(args.duration, args.imu_rate,
                                                       labels=option_labels(args))
    start = time.perf_counter()
    episode = simulate(config, seed=args.seed, ideal=args.ideal)
    path = episode.save(args.out)
    elapsed = time.perf_counter() - start
    euler = quat_to_euler(episode.truth.q_b_n)
    print(f"{config.name}: {config.duration:g} s, IMU {config.imu_rate:g} Hz "
          f"({episode.dtheta.shape[0]} samples, {'ideal' if args.ideal else config.imu_preset}),"
          f" seed {args.seed}, {elapsed:.2f} s wall")
    print("  hull pitch/roll/yaw range: "
          + ", ".join(f"[{lo:.1f}, {hi:.1f}] deg" for lo, hi in
                      zip(euler.min(0) / deg, euler.max(0) / deg)))
    print(f"  wrote {path}")
    return 0
