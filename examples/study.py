"""The learned-tuning study of one scenario: does an agent that retunes a filter beat the
paper's own adaptive filters on episodes it never saw?

Arms, each scored on the first ``--test`` episodes of the test split (seeds no arm saw):
- every filter of the scenario's experiment as tuned (the zero action);
- the base filter (the KF, or the EKF / classic KF on the nonlinear models), as tuned;
- the base filter with the best constant retune: cross-entropy over the action on the
  first ``--ce-episodes`` training episodes;
- the base filter retuned at every epoch by a PPO policy (stable-baselines3) that acts on
  the env's observation, trained for ``--ppo-steps`` steps on the first ``--train``
  training episodes (the native vector env, 16 slots); ``--ppo-seeds``, ``--normalize``
  (VecNormalize) and ``--reward`` (the reward both agents train on; every arm is scored
  on the default) vary it.

All episodes come from one episode bank (built first, in parallel). For each arm: the
mean reward per epoch and the RMS final heading error with 95 % bootstrap intervals over
the test episodes, the median final heading and the diverged count. Writes a JSON file
and prints a Markdown table. Needs the extra: pip install -e '.[agents]'.

Run: python examples/study.py SCENARIO [--train 128] [--test 50] [--ppo-steps 200000]
     [--ppo-seeds 1] [--normalize] [--reward attitude] [--episode-length S] [--bank DIR]
     [--out FILE.json]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy import stats

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.scenarios.bank import EpisodeBank, split_seeds
from aligngym.scenarios.env import REWARDS
from aligngym.scenarios.experiments import env_experiment
from aligngym.scenarios.vector_env import AlignmentVectorEnv

BASE = {"paper000": "ekf", "paper001": "lckf", "paper002": "ekf", "paper003": "kf",
        "paper004": "ekf"}
"""The conventional filter an agent retunes, per experiment."""
SLOTS = 16


def score(env: AlignmentVectorEnv, seeds: list[int], policy) -> dict[str, np.ndarray]:
    """Run each seed's episode once (a slot each) under policy(obs) -> actions; per
    episode: its summed reward per epoch of the episode's length (a diverged one is
    charged the worst reward for the epochs it did not run, by the env), its final
    heading error (arcmin) and whether it diverged."""
    obs, _ = env.reset(options={"episode_seed": seeds})
    n = env.num_envs
    total = np.zeros(n)
    heading, diverged = np.full(n, np.nan), np.zeros(n, bool)
    live = np.ones(n, bool)
    while live.any():
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total[live] += reward[live]
        for i in np.flatnonzero(live & (terminated | truncated)):
            heading[i] = info["metrics"]["final_phi_U_arcmin"][i]
            diverged[i] = bool(info["metrics"]["diverged"][i])
        live &= ~(terminated | truncated)
    return {"reward": total / env.episode_steps, "heading": heading, "diverged": diverged}


def interval(values: np.ndarray, statistic) -> tuple[float, float, float]:
    """The statistic and its 95 % bootstrap interval (percentile, 2000 resamples, fixed seed)."""
    value = float(statistic(values))
    if np.ptp(values) == 0.0:                    # every episode the same (an arm vs itself)
        return value, value, value
    ci = stats.bootstrap((values,), statistic, confidence_level=0.95, n_resamples=2000,
                         random_state=np.random.default_rng(0), method="percentile")
    return value, float(ci.confidence_interval.low), float(ci.confidence_interval.high)


def summarise(arm: str, filter_name: str, result: dict, reference: dict,
              extra: dict | None = None) -> dict:
    """The arm's statistics, and the paired difference of its reward per epoch from
    reference's (the base filter as tuned on the same episodes) with its interval."""
    rms = lambda x, axis=-1: np.sqrt(np.mean(np.square(x), axis=axis))  # noqa: E731
    reward = interval(result["reward"], lambda x, axis=-1: np.mean(x, axis=axis))
    heading = interval(result["heading"], rms)
    return {"arm": arm, "filter": filter_name, "reward_per_epoch": reward,
            "heading_rms_arcmin": heading,
            "heading_median_abs_arcmin": float(np.median(np.abs(result["heading"]))),
            "diverged": int(result["diverged"].sum()), "episodes": int(result["reward"].size),
            "reward_gain_vs_base": interval(result["reward"] - reference["reward"],
                                            lambda x, axis=-1: np.mean(x, axis=axis)),
            "per_episode": {"reward": result["reward"].round(6).tolist(),  # for other pairings
                            "heading_arcmin": result["heading"].round(6).tolist()},
            **(extra or {})}


def constant(action: np.ndarray, n: int):
    return lambda obs: np.broadcast_to(action, (n, action.size)).astype(np.float32)


def cross_entropy(make, seeds: list[int], iterations: int, population: int,
                  reward: str, elite: int = 3) -> tuple[np.ndarray, list[float]]:
    """The constant action with the best mean training reward (one batched run of the
    training episodes per candidate)."""
    env = make(len(seeds), "train", reward=reward)
    rng = np.random.default_rng(0)
    dim = env.single_action_space.shape[0]
    mean, std, history = np.zeros(dim), np.full(dim, 0.5), []
    for _ in range(iterations):
        candidates = np.clip(mean + std * rng.standard_normal((population, dim)), -1, 1)
        candidates[0] = mean
        scores = np.array([score(env, seeds, constant(c, len(seeds)))["reward"].mean()
                           for c in candidates])
        best = candidates[np.argsort(scores)[-elite:]]
        mean, std = best.mean(0), np.maximum(best.std(0), 0.05)
        history.append(float(scores.max()))
    env.close()
    return mean.astype(np.float32), history


def sb3_vec_env(env: AlignmentVectorEnv):
    """The native vector env (same-step autoreset) as a stable-baselines3 VecEnv."""
    from stable_baselines3.common.vec_env import VecEnv

    class AlignmentSb3(VecEnv):
        def __init__(self) -> None:
            super().__init__(env.num_envs, env.single_observation_space,
                             env.single_action_space)

        def reset(self):
            seeds = None if all(s is None for s in self._seeds) else self._seeds
            obs, _ = env.reset(seed=seeds)             # PPO(seed=k) seeds slot i with k + i
            self._reset_seeds()
            return obs

        def step_async(self, actions) -> None:
            self._actions = np.asarray(actions, np.float32)

        def step_wait(self):
            obs, reward, terminated, truncated, info = env.step(self._actions)
            done = terminated | truncated
            infos = [{} for _ in range(env.num_envs)]
            for i in np.flatnonzero(done):
                infos[i] = {"terminal_observation": info["final_obs"][i],
                            "TimeLimit.truncated": bool(truncated[i] and not terminated[i])}
            return obs, reward.astype(np.float32), done, infos

        def close(self) -> None:
            env.close()

        def get_attr(self, name, indices=None):
            return [getattr(env, name)] * len(self._get_indices(indices))

        def set_attr(self, name, value, indices=None) -> None:
            setattr(env, name, value)

        def env_method(self, name, *args, indices=None, **kwargs):
            return [getattr(env, name)(*args, **kwargs)] * len(self._get_indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return AlignmentSb3()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario")
    parser.add_argument("--train", type=int, default=128)
    parser.add_argument("--test", type=int, default=50)
    parser.add_argument("--ce-episodes", type=int, default=32)
    parser.add_argument("--ce-iterations", type=int, default=4)
    parser.add_argument("--ce-population", type=int, default=8)
    parser.add_argument("--ppo-steps", type=int, default=200_000)
    parser.add_argument("--ppo-seeds", type=int, default=1, help="PPO runs, seeds 0 ..")
    parser.add_argument("--reward", default="attitude", choices=REWARDS,
                        help="the reward the agents train on (scoring uses the default)")
    parser.add_argument("--normalize", action="store_true",
                        help="PPO on VecNormalize (running obs and return scaling)")
    parser.add_argument("--episode-length", type=float, default=600.0)
    parser.add_argument("--bank", default="bank")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    clock = time.perf_counter()
    experiment = env_experiment(args.scenario, args.episode_length, 1.0)
    name = type(experiment).__module__.rsplit(".", 1)[-1]
    base = BASE[name]
    filters = [f for f in dict.fromkeys([*experiment.default_filters, base])]
    bank = EpisodeBank(args.bank, experiment)
    train, test = split_seeds("train", args.train), split_seeds("test", args.test)
    bank.build(train + test, workers=args.workers)
    bank_s = time.perf_counter() - clock

    def make(n: int, split: str, estimator: str = base, **kwargs) -> AlignmentVectorEnv:
        """n slots on a split (a reset after a divergence draws among its banked seeds)."""
        return AlignmentVectorEnv(n, scenario=args.scenario, estimator=estimator,
                                  episode_length=args.episode_length, bank=args.bank,
                                  split=split, split_episodes=len(train if split == "train"
                                                                  else test),
                                  cache_episodes=0, **kwargs)

    tuned = {}
    for f in filters:                                  # as tuned
        env = make(len(test), "test", f)
        zero = np.zeros(env.single_action_space.shape, np.float32)
        tuned[f] = score(env, test, constant(zero, len(test)))
        env.close()
    rows = [summarise("as tuned", f, tuned[f], tuned[base]) for f in filters]
    start = time.perf_counter()
    action, history = cross_entropy(make, train[:args.ce_episodes], args.ce_iterations,
                                    args.ce_population, args.reward)
    env = make(len(test), "test")
    trained_on = f", {args.reward} reward" if args.reward != "attitude" else ""
    rows.append(summarise("constant retune (CE)" + trained_on, base, score(
        env, test, constant(action, len(test))), tuned[base],
        {"action": action.round(3).tolist(), "train_reward": history,
         "wall_s": time.perf_counter() - start}))
    env.close()
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize
    for seed in range(args.ppo_seeds):
        start = time.perf_counter()
        vec = sb3_vec_env(make(SLOTS, "train", autoreset_mode="SameStep",
                               reward=args.reward))
        if args.normalize:                     # running mean/std of obs and of the return
            vec = VecNormalize(vec, norm_obs=True, norm_reward=True, gamma=0.99)
        model = PPO("MlpPolicy", vec, n_steps=256, batch_size=256, learning_rate=3e-4,
                    gamma=0.99, seed=seed, verbose=0, device="cpu")
        model.learn(total_timesteps=args.ppo_steps)
        trained = time.perf_counter() - start
        prepare = vec.normalize_obs if args.normalize else (lambda obs: obs)  # frozen stats
        env = make(len(test), "test")
        arm = "PPO policy" + (", normalised" if args.normalize else "") + trained_on + (
            f", seed {seed}" if args.ppo_seeds > 1 else "")
        rows.append(summarise(arm, base, score(
            env, test, lambda obs: model.predict(prepare(obs), deterministic=True)[0]),
            tuned[base], {"ppo_steps": args.ppo_steps, "ppo_seed": seed,
                          "normalize": args.normalize, "wall_s": trained}))
        env.close()
        vec.close()
    out = {"scenario": args.scenario, "experiment": name, "episode_length_s":
           args.episode_length, "train_episodes": args.train, "test_episodes": args.test,
           "test_seeds": [test[0], test[-1]], "train_reward": args.reward,
           "ppo_seeds": args.ppo_seeds, "normalize": args.normalize, "bank_s": bank_s,
           "wall_s": time.perf_counter() - clock, "rows": rows}
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"{args.scenario}: {args.test} test episodes, {args.train} training, "
          f"{out['wall_s']:.0f} s")
    print(f"| arm | filter | reward / epoch [95 % CI] | gain over `{base}` as tuned "
          "(paired) [95 % CI] | heading RMS, ' [95 % CI] | median abs heading, ' | "
          "diverged |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        (rw, rl, rh), (hw, hl, hh) = r["reward_per_epoch"], r["heading_rms_arcmin"]
        gw, gl, gh = r["reward_gain_vs_base"]
        print(f"| {r['arm']} | `{r['filter']}` | {rw:.2f} [{rl:.2f}, {rh:.2f}] | "
              f"{gw:+.2f} [{gl:+.2f}, {gh:+.2f}] | {hw:.2f} [{hl:.2f}, {hh:.2f}] | "
              f"{r['heading_median_abs_arcmin']:.2f} | {r['diverged']} |")


if __name__ == "__main__":
    main()
