"""Benchmark: the native vector env (N episodes through batched filters in one process)
against gymnasium's AsyncVectorEnv of N single envs (one process each), steps per second
of the N slots together after the reset, both resetting from the same episode bank; and
one env's reset from the bank against a fresh simulation.
With slots that end at different times (``--groups``: the slots' episodes end in G
groups at G different steps; 16 groups of one is the worst case) as well as aligned.
Run: python benchmarks/bench_vector_env.py [--envs 16] [--steps 200] [--scenario ID]
     [--groups 4 16]"""
from __future__ import annotations

import argparse
import tempfile
import time

import gymnasium as gym
import numpy as np

import aligngym  # noqa: F401
from aligngym.scenarios.bank import EpisodeBank, split_seeds
from aligngym.scenarios.experiments import experiment_for


def steps_per_second(envs, steps: int, groups: int = 1) -> float:
    """Steps per second of all slots together over ``steps`` steps after the reset.
    groups > 1: the slots end at different times: after the reset, group g's slots are
    reset again at step g (groups of num_envs / groups slots), so that the groups'
    episodes end and restart at different steps (same-step autoreset), as diverging
    episodes make them; the native vector env keeps them in its one batched filter,
    each group at its own epoch."""
    envs.reset(seed=0)
    actions = np.zeros(envs.action_space.shape, np.float32)
    n = envs.num_envs
    for g in range(1, groups):
        mask = np.zeros(n, bool)
        mask[g * n // groups:(g + 1) * n // groups] = True
        envs.step(actions)
        envs.reset(options={"reset_mask": mask})
    start = time.perf_counter()
    for _ in range(steps):
        envs.step(actions)
    elapsed = time.perf_counter() - start
    envs.close()
    return steps * envs.num_envs / elapsed


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--scenario", default="ship-sway-rotary")
    parser.add_argument("--estimator", default="kf")
    parser.add_argument("--groups", type=int, nargs="*", default=[4, 16],
                        help="also measure slots ending in this many groups (mixed ends)")
    args = parser.parse_args()
    env_id = "aligngym/" + "".join(w.capitalize() for w in args.scenario.split("-")) + "-v1"
    length = float(max(20, args.steps // 2))   # every slot ends (and restarts) once
    with tempfile.TemporaryDirectory() as bank:
        kwargs = dict(estimator=args.estimator, episode_length=length, bank=bank,
                      split="train", split_episodes=args.envs)
        experiment = experiment_for(args.scenario, fine_duration=length, filter_step=1.0)
        start = time.perf_counter()
        EpisodeBank(bank, experiment).build(split_seeds("train", args.envs), workers=2,
                                            progress=False)
        print(f"bank of {args.envs} episodes: {time.perf_counter() - start:.1f} s (2 workers)")
        # One env's reset: fresh simulation, then from the bank.
        for name, extra in (("fresh simulation", {"bank": None}), ("bank", {})):
            env = gym.make(env_id, **{**kwargs, **extra}, cache_episodes=0)
            start = time.perf_counter()
            for s in range(3):
                env.reset(options={"episode_seed": s})
            print(f"reset from {name}: {(time.perf_counter() - start) / 3 * 1e3:.0f} ms")
            env.close()
        for groups in (1, *args.groups):
            ends = "aligned" if groups == 1 else f"ends in {groups} groups"
            native = steps_per_second(gym.make_vec(
                env_id, num_envs=args.envs, autoreset_mode="SameStep", **kwargs),
                args.steps, groups)
            print(f"native vector env, N = {args.envs}, {ends}: {native:.0f} steps/s")
            asynchronous = steps_per_second(gym.make_vec(
                env_id, num_envs=args.envs, vectorization_mode="async",
                vector_kwargs={"autoreset_mode": "SameStep"}, **kwargs), args.steps, groups)
            print(f"async vector env, N = {args.envs}, {ends}: {asynchronous:.0f} steps/s")
            print(f"native / async, {ends}: {native / asynchronous:.1f}x")


if __name__ == "__main__":
    main()
