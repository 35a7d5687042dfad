"""The alignment env in stable-baselines3: PPO learns a state-feedback retuning of the
mistuned KF of ``tune_agent.py`` on the swaying ship (the policy sees the filter's own
observation each epoch), then is scored against the zero action on held-out episodes.
A smoke run: a short training budget shows the env plugs into a standard RL library,
not a tuned agent. Needs the extra: pip install -e '.[agents]'.

Run: python examples/ppo_smoke.py [--timesteps N] [--episode-length S]
"""
from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import aligngym  # noqa: F401  (registers the env ids)

MISTUNED = {"measurement": 0.01}
TEST_SEEDS = (21, 22, 23)


def mean_reward(env: gym.Env, policy, seeds) -> float:
    """Mean reward per epoch over the seeds' episodes, actions from policy(obs)."""
    from tune_agent import run_episode
    return float(np.mean([total / steps for total, steps, _ in
                          (run_episode(env, policy, seed) for seed in seeds)]))


def main() -> None:
    from stable_baselines3 import PPO

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=4096)
    parser.add_argument("--episode-length", type=float, default=60.0)
    args = parser.parse_args()
    make = lambda: gym.make("aligngym/ShipSwayRotary-v1", estimator="kf",  # noqa: E731
                            episode_length=args.episode_length, mistuning=MISTUNED,
                            cache_episodes=64)
    env = make()
    start = time.perf_counter()
    model = PPO("MlpPolicy", env, n_steps=256, batch_size=64, learning_rate=3e-4, seed=0,
                verbose=0)
    model.learn(total_timesteps=args.timesteps)
    trained = time.perf_counter() - start
    test = make()
    zero = np.zeros(test.action_space.shape, np.float32)
    ppo = mean_reward(test, lambda obs: model.predict(obs, deterministic=True)[0],
                      TEST_SEEDS)
    still = mean_reward(test, lambda obs: zero, TEST_SEEDS)
    print(f"PPO, {args.timesteps} steps of {args.episode_length:g} s episodes "
          f"({trained:.0f} s): mean reward per epoch on held-out episodes {ppo:.2f}, "
          f"zero action {still:.2f}")


if __name__ == "__main__":
    main()
