"""A small black-box agent: cross-entropy search over a constant action that retunes a
deliberately mistuned filter in the alignment env.

The filter is the conventional KF tuned for a calm sea (measurement noise 10x too small
in sigma) on the swaying ship. The agent searches the action (log-scale multipliers on
the noise variances) that maximises the mean episode reward on a fixed set of episodes
(common random numbers), then compares it with the zero action on fresh episodes.

Run: python examples/tune_agent.py
"""
from __future__ import annotations

import numpy as np
import gymnasium as gym

import aligngym  # noqa: F401  (registers the env ids)

MISTUNED = {"measurement": 0.01}


def run_episode(env: gym.Env, policy, seed: int) -> tuple[float, int, dict]:
    """One episode of the given seed: the summed reward, the steps taken and the last
    step's info; policy: a constant action, or a function of the observation."""
    obs, _ = env.reset(seed=seed, options={"episode_seed": seed})
    total, steps = 0.0, 0
    while True:
        action = policy(obs) if callable(policy) else policy
        obs, reward, terminated, truncated, info = env.step(action)
        total, steps = total + reward, steps + 1
        if terminated or truncated:
            return total, steps, info


def episode_return(env: gym.Env, action: np.ndarray, seed: int) -> float:
    return run_episode(env, action, seed)[0] / env.unwrapped.episode_steps


def mean_return(env: gym.Env, action: np.ndarray, seeds: list[int]) -> float:
    return float(np.mean([episode_return(env, action, s) for s in seeds]))


def cross_entropy_search(env: gym.Env, seeds: list[int], iterations: int = 4,
                         population: int = 8, elite: int = 2, rng_seed: int = 0
                         ) -> tuple[np.ndarray, list[float]]:
    """Constant action maximising the mean reward; returns it and the best score per
    iteration."""
    rng = np.random.default_rng(rng_seed)
    dim = env.action_space.shape[0]
    mean, std = np.zeros(dim), np.full(dim, 0.5)
    history = []
    for _ in range(iterations):
        candidates = np.clip(mean + std * rng.standard_normal((population, dim)), -1, 1)
        candidates[0] = mean
        scores = np.array([mean_return(env, c.astype(np.float32), seeds) for c in candidates])
        best = candidates[np.argsort(scores)[-elite:]]
        mean, std = best.mean(0), np.maximum(best.std(0), 0.05)
        history.append(float(scores.max()))
    return mean.astype(np.float32), history


def main(episode_length: float = 120.0, train_seeds=(11, 12, 13), test_seeds=(21, 22, 23),
         iterations: int = 4, population: int = 8) -> dict:
    env = gym.make("aligngym/ShipSwayRotary-v1", estimator="kf", episode_length=episode_length,
                   mistuning=MISTUNED, cache_episodes=len(train_seeds) + len(test_seeds))
    action, history = cross_entropy_search(env, list(train_seeds), iterations, population)
    zero = np.zeros(env.action_space.shape, np.float32)
    result = {"action": action, "history": history,
              "zero_test": mean_return(env, zero, list(test_seeds)),
              "agent_test": mean_return(env, action, list(test_seeds))}
    env.close()
    return result


if __name__ == "__main__":
    out = main()
    print(f"action found: {np.round(out['action'], 3)} (gyro q, accel q, R multipliers, "
          "log10 / 2)")
    print(f"mean reward per epoch on unseen episodes: zero action {out['zero_test']:.3f}, "
          f"agent {out['agent_test']:.3f}")
