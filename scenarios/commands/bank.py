"""aligngym bank: a split's episodes of a scenario simulated once into an episode bank."""
from __future__ import annotations

import argparse
import time

from aligngym.scenarios.commands.options import (EXECUTOR_CHOICES, float_option,
                                                 integer_option, settings_of)
from aligngym.scenarios.registry import scenario_names


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``bank`` command's options."""
    bank_help = ("simulate a split's episodes of a scenario once into an episode bank, which "
                 "the env's reset loads (gym.make(..., bank=DIR, split=SPLIT))")
    bnk = sub.add_parser("bank", help=bank_help, description=bank_help)
    bnk.add_argument("scenario", metavar="SCENARIO", help="scenario name (" + ", ".join(
        scenario_names()) + ") or a .toml file that names an experiment")
    bnk.add_argument("--out", required=True, metavar="DIR", help="the bank directory")
    bnk.add_argument("--split", choices=["train", "validation", "test"], default="train",
                     help="the seed split (train [0, 1.6e9), validation [1.6e9, 1.8e9), "
                     "test [1.8e9, 2^31 - 1); default: train)")
    bnk.add_argument("--episodes", type=integer_option("--episodes"), default=100,
                     metavar="N", help="episodes: the split's seeds FIRST .. FIRST + N - 1 "
                     "(default: 100)")
    bnk.add_argument("--first", type=integer_option("--first", minimum=0), default=0,
                     metavar="K",
                     help="the first episode of the split (default: 0)")
    bnk.add_argument("--episode-length", type=float_option("--episode-length"),
                     default=600.0, metavar="S", help="the env's episode_length, s "
                     "(default: 600)")
    bnk.add_argument("--epoch-length", type=float_option("--epoch-length"), default=1.0,
                     metavar="S", help="the env's epoch_length, s (default: 1)")
    bnk.add_argument("--set", action="append", metavar="NAME=VALUE",
                     help="a setting of the scenario's experiment, as the env's settings "
                     "(e.g. coarse_duration=60); repeatable")
    bnk.add_argument("--workers", type=integer_option("--workers"), metavar="K",
                     help="parallel processes, or CPUs of a local Ray instance "
                     "(default: all cores)")
    bnk.add_argument("--executor", choices=EXECUTOR_CHOICES, default="local",
                     help="local processes or Ray tasks (default: local)")
    bnk.add_argument("--address", metavar="ADDR", help="with --executor ray: the cluster")


def run(args: argparse.Namespace) -> int:
    import os

    from aligngym.scenarios.bank import EpisodeBank, check_split, split_seeds
    from aligngym.scenarios.campaign.engine import check_seed_memory
    from aligngym.scenarios.campaign.executors import executor_named
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.experiments import env_experiment, experiment_class

    config = load_scenario(args.scenario)
    args.paper = config.experiment or "the scenario's experiment"
    args.setting_labels = {"fine_duration": "--episode-length", "filter_step": "--epoch-length"}
    settings = settings_of(experiment_class(config.experiment), args) if (
        config.experiment and args.set) else {}
    lo, hi = check_split(args.split)
    if args.first + args.episodes <= hi - lo:     # a seed list the machine can hold
        check_seed_memory(args.episodes)
    seeds = split_seeds(args.split, args.episodes, args.first)
    experiment = env_experiment(args.scenario, args.episode_length, args.epoch_length,
                                settings, config=config)
    executor_named(args.executor, args.address)       # before the bank's directory is made
    bank = EpisodeBank(args.out, experiment)
    start = time.perf_counter()
    simulated = bank.build(seeds, workers=args.workers or os.cpu_count() or 1,
                           executor=args.executor, address=args.address)
    print(f"{bank.directory}: {len(seeds)} {args.split} episodes (seeds {seeds[0]} .. "
          f"{seeds[-1]}), {simulated} simulated, {len(seeds) - simulated} already there; "
          f"{time.perf_counter() - start:.1f} s")
    return 0
