"""The learned-tuning study of one scenario: does an agent that retunes a filter beat the
paper's own adaptive filters on episodes it never saw, and how much is there to gain?

Arms, each scored on the first ``--test`` episodes of the test split (seeds no arm saw):
- every filter of the scenario's experiment as tuned (the zero action), and the
  textbook adaptive baseline, the Sage-Husa filter, where the base filter runs on the
  experiment's own model (not paper 001's lckf, a model variant);
- the base filter (the KF, or the EKF / classic KF on the nonlinear models), as tuned;
- the base filter with the best constant retune: cross-entropy over the action on the
  first ``--ce-episodes`` training episodes;
- on a scenario with a [[schedule]], the oracle: the base filter with the best constant
  retune per segment of the schedule (it knows when the disturbance changes, not the
  episode), cross-entropy over all segments' actions at once on the same training
  episodes, from the best constant retune;
- the base filter retuned at every epoch by a learned policy that acts on the env's
  observation (``--algo``: PPO from stable-baselines3, recurrent PPO from sb3-contrib),
  trained for ``--ppo-steps`` steps on the first ``--train`` training episodes (the
  native vector env, 16 slots); ``--ppo-seeds``, ``--normalize`` (VecNormalize, its
  statistics frozen for the test) and ``--reward`` (the reward the agents train on;
  every arm is scored on the default) vary it;
- your own agents (``--agent NAME=module.path:factory``).

All episodes come from one episode bank (built first, in parallel). For each arm: the
mean reward per epoch and the RMS final heading error with 95 % bootstrap intervals over
the test episodes, the median final heading and the diverged count. With a schedule, the
headroom (oracle minus best constant retune, 95 % paired bootstrap interval) and each
arm's fraction of it; ``--headroom FILE`` records them in the leaderboard file. Writes a
JSON file (``--out``, with the agents' learning curves) and prints Markdown tables. The
learned arms need the extra: pip install -e '.[agents]'.

Run: python examples/study.py SCENARIO [--train 128] [--test 50] [--ppo-steps 200000]
     [--ppo-seeds 1] [--algo ppo recurrent-ppo] [--normalize] [--reward attitude]
     [--agent NAME=module.path:factory] [--episode-length S] [--bank DIR]
     [--out FILE.json] [--headroom docs/study/headroom.json]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy import stats

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.estimators.catalogue import filter_entry
from aligngym.scenarios.bank import EpisodeBank, split_seeds
from aligngym.scenarios.env_core import REWARDS, episode_step_count
from aligngym.scenarios.experiments import env_experiment
from aligngym.scenarios.vector_env import AlignmentVectorEnv

BASE = {"paper000": "ekf", "paper001": "lckf", "paper002": "ekf", "paper003": "kf",
        "paper004": "ekf"}
"""The conventional filter an agent retunes, per experiment."""
SLOTS = 16


def score(env: AlignmentVectorEnv, seeds: list[int], policy) -> dict[str, np.ndarray]:
    """Run each seed's episode once (a slot each, all from step 0) under policy(obs, k)
    -> actions at step k; per episode: its summed reward per epoch of the episode's
    length (a diverged one is charged the worst reward for the epochs it did not run, by
    the env), its final heading error (arcmin) and whether it diverged."""
    obs, _ = env.reset(options={"episode_seed": seeds})
    n = env.num_envs
    total = np.zeros(n)
    heading, diverged = np.full(n, np.nan), np.zeros(n, bool)
    live = np.ones(n, bool)
    k = 0
    while live.any():
        obs, reward, terminated, truncated, info = env.step(policy(obs, k))
        k += 1
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


def headroom(scenario: str, default: dict, best_constant: dict, oracle: dict,
             arms: dict[str, dict]) -> dict:
    """The leaderboard entry of a scenario with a schedule: mean reward per epoch on the
    test episodes of the base filter as tuned (default), its best constant retune and the
    oracle (a constant retune per segment, knowing the schedule); the headroom (oracle
    minus best constant) with its 95 % paired bootstrap interval; per arm its score and
    the fraction of the headroom it closes, (arm - best constant) / headroom, with the
    interval of that ratio over the same paired resamples of episodes."""
    c, o = best_constant["reward"], oracle["reward"]
    rng = np.random.default_rng(0)
    resamples = rng.integers(0, c.size, (2000, c.size))     # episodes, paired across arms
    gap = (o - c)[resamples].mean(1)
    entry = {"scenario": scenario, "episodes": int(c.size),
             "default": float(default["reward"].mean()), "best_constant": float(c.mean()),
             "oracle": float(o.mean()), "headroom": float((o - c).mean()),
             "headroom_ci95": np.percentile(gap, [2.5, 97.5]).tolist(), "arms": {}}
    for arm, result in arms.items():
        r = result["reward"]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios = (r - c)[resamples].mean(1) / gap
            fraction = (r - c).mean() / (o - c).mean()
        usable = np.isfinite(ratios).any() and np.isfinite(fraction)   # no headroom: None
        entry["arms"][arm] = {
            "score": float(r.mean()), "fraction": float(fraction) if usable else None,
            "fraction_ci95": np.nanpercentile(ratios, [2.5, 97.5]).tolist() if usable
            else None}
    return entry


def record_headroom(path: Path, entry: dict) -> None:
    """Write entry into the leaderboard file (a list of entries, one per scenario: the
    scenario's earlier entry is replaced), atomically."""
    from aligngym.scenarios.atomic import write_json
    entries = json.loads(path.read_text()) if path.is_file() else []
    entries = [e for e in entries if e["scenario"] != entry["scenario"]] + [entry]
    write_json(path, sorted(entries, key=lambda e: e["scenario"]))


def print_headroom(entry: dict) -> None:
    lo, hi = entry["headroom_ci95"]
    print(f"\nheadroom (oracle - best constant): {entry['headroom']:+.3f} [{lo:+.3f}, "
          f"{hi:+.3f}] per epoch = {entry['headroom'] / abs(entry['default']):.0%} of the "
          f"default's {entry['default']:.3f}")
    print("| arm | reward / epoch | fraction of the headroom [95 % CI] |")
    print("| --- | --- | --- |")
    for arm, a in entry["arms"].items():
        if a["fraction"] is None:                       # no headroom to close
            print(f"| {arm} | {a['score']:.3f} | n/a |")
            continue
        flo, fhi = a["fraction_ci95"]
        print(f"| {arm} | {a['score']:.3f} | {a['fraction']:+.2f} [{flo:+.2f}, {fhi:+.2f}] |")


def constant(action: np.ndarray, n: int):
    """The policy that takes action (A,) in every slot at every step."""
    return piecewise(np.asarray(action)[None], [], n)


def piecewise(actions: np.ndarray, starts: list[int], n: int):
    """The policy of n slots that takes, during segment j (steps [starts[j - 1],
    starts[j]); starts: the S - 1 first steps of segments 1 ..), actions[j] in every
    slot (actions (S, A)) or actions[i, j] in slot i (actions (n, S, A))."""
    actions = np.asarray(actions, np.float32)

    def policy(obs, k: int) -> np.ndarray:
        j = int(np.searchsorted(starts, k, side="right"))
        if actions.ndim == 3:
            return actions[:, j]
        return np.broadcast_to(actions[j], (n, actions.shape[1]))
    return policy


def segment_starts(schedule, fine_start: float, dt: float, steps: int) -> list[int]:
    """The steps where the schedule's segments (``Schedule.boundaries``, scenario time s)
    begin within a fine run of ``steps`` epochs of dt s from fine_start s: step k's
    update is at fine_start + (k + 1) dt; a segment's first step is the first whose
    update lies beyond its boundary."""
    updates = fine_start + (np.arange(steps) + 1) * dt
    firsts = {int(np.searchsorted(updates, edge, side="right"))
              for edge in schedule.boundaries()}
    return sorted(k for k in firsts if 0 < k < steps)


def cross_entropy(make, seeds: list[int], iterations: int, population: int,
                  reward: str, elite: int = 3, starts: list[int] = (),
                  initial: np.ndarray | None = None) -> tuple[np.ndarray, list[float]]:
    """The piecewise-constant action (len(starts) + 1 segments, ``piecewise``; one
    segment: a constant action) with the best mean training reward, by the
    cross-entropy method from initial (S, A; None: zeros, the filter as tuned). Each
    iteration runs the whole population at once: one batched run of population x
    len(seeds) slots (the batch's episodes are independent: the same numbers as one run
    per candidate), the current mean as its first candidate. Returns the best candidate
    evaluated and the best training reward per iteration."""
    n = len(seeds)
    env = make(n * population, "train", reward=reward)
    rng = np.random.default_rng(0)
    shape = (len(starts) + 1, env.single_action_space.shape[0])
    mean = np.zeros(shape).ravel() if initial is None else np.asarray(initial, float).ravel()
    std, history = np.full(mean.size, 0.5), []
    best, best_score = mean, -np.inf
    for _ in range(iterations):
        candidates = np.clip(mean + std * rng.standard_normal((population, mean.size)), -1, 1)
        candidates[0] = mean
        slots = np.repeat(candidates.reshape((population,) + shape), n, axis=0)  # (P n, S, A)
        scores = score(env, list(seeds) * population, piecewise(
            slots, list(starts), n * population))["reward"].reshape(population, n).mean(1)
        if scores.max() > best_score:
            best, best_score = candidates[np.argmax(scores)], float(scores.max())
        top = candidates[np.argsort(scores)[-elite:]]
        mean, std = top.mean(0), np.maximum(top.std(0), 0.05)
        history.append(float(scores.max()))
    env.close()
    return best.reshape(shape).astype(np.float32), history


def sb3_vec_env(env: AlignmentVectorEnv, curve: "LearningCurve | None" = None):
    """The native vector env (same-step autoreset) as a stable-baselines3 VecEnv; curve:
    records each finished episode's reward."""
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
            if curve is not None:
                curve.track(reward, done)
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


def tuned_actions(path: str) -> dict[str, np.ndarray]:
    """The best constant retune (1, A) and the oracle's actions (S, A) an earlier study
    of the same scenario found (its --out file; ``--tuned-from``), to score them again
    without tuning them again."""
    rows = json.loads(Path(path).read_text())["rows"]
    found = {}
    for r in rows:
        if r["arm"].startswith("constant retune"):
            found["constant"] = np.asarray([r["action"]], np.float32)
        elif r["arm"].startswith("oracle"):
            found["oracle"] = np.asarray(r["actions"], np.float32)
    return found


def load_agent(target: str):
    """The factory "module.path:name" names (``--agent``); a one-line error otherwise."""
    import importlib
    module, _, name = target.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise SystemExit(f"--agent {target!r}: {exc} (write NAME=module.path:factory)")


AGENTS = {"ppo": "PPO policy", "recurrent-ppo": "recurrent PPO policy"}
"""The learned arms (stable-baselines3; recurrent PPO from sb3-contrib)."""


class LearningCurve:
    """The record of a training on num_envs slots: per finished episode, the training
    step and its reward per epoch (the reward the agent trains on)."""

    def __init__(self, num_envs: int, steps_per_episode: int) -> None:
        self.steps_per_episode, self.curve = steps_per_episode, []
        self._total, self._step = np.zeros(num_envs), 0

    def track(self, reward: np.ndarray, done: np.ndarray) -> None:
        self._total += reward
        self._step += self._total.size
        for i in np.flatnonzero(done):
            self.curve.append((self._step, float(self._total[i] / self.steps_per_episode)))
            self._total[i] = 0.0


def train_agent(algo: str, make, seed: int, args):
    """Train one agent on the training split (16 slots of the native vector env, the
    episodes reset in the same step), VecNormalize with --normalize; returns the model,
    its VecEnv and its learning curve ((training step, reward per epoch) per episode)."""
    from stable_baselines3.common.vec_env import VecNormalize
    env = make(SLOTS, "train", autoreset_mode="SameStep", reward=args.reward)
    curve = LearningCurve(env.num_envs, env.episode_steps)
    vec = sb3_vec_env(env, curve)
    outer = VecNormalize(vec, norm_obs=True, norm_reward=True, gamma=0.99) \
        if args.normalize else vec
    if algo == "ppo":
        from stable_baselines3 import PPO
        model = PPO("MlpPolicy", outer, n_steps=256, batch_size=256, learning_rate=3e-4,
                    gamma=0.99, seed=seed, verbose=0, device="cpu")
    else:
        from sb3_contrib import RecurrentPPO
        model = RecurrentPPO("MlpLstmPolicy", outer, n_steps=256, batch_size=256,
                             learning_rate=3e-4, gamma=0.99, seed=seed, verbose=0,
                             device="cpu")
    model.learn(total_timesteps=args.ppo_steps)
    if args.normalize:
        outer.training = False                 # frozen statistics from here on
    return model, outer, curve.curve


def agent_policy(model, vec, n: int, algo: str):
    """policy(obs, k) of a trained agent, deterministic; observations normalised by the
    training's frozen statistics where it had them; a recurrent agent's memory starts
    at step 0."""
    prepare = vec.normalize_obs if hasattr(vec, "normalize_obs") else (lambda obs: obs)
    if algo == "ppo":
        return lambda obs, k: model.predict(prepare(obs), deterministic=True)[0]
    memory = {}

    def policy(obs, k):
        if k == 0:
            memory["state"] = None
        action, memory["state"] = model.predict(
            prepare(obs), state=memory["state"], episode_start=np.full(n, k == 0),
            deterministic=True)
        return action
    return policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario")
    parser.add_argument("--train", type=int, default=128)
    parser.add_argument("--test", type=int, default=50)
    parser.add_argument("--ce-episodes", type=int, default=32)
    parser.add_argument("--ce-iterations", type=int, default=4)
    parser.add_argument("--ce-population", type=int, default=8)
    parser.add_argument("--oracle-iterations", type=int, default=6)
    parser.add_argument("--oracle-population", type=int, default=16)
    parser.add_argument("--ppo-steps", type=int, default=200_000, help="0: no PPO arm")
    parser.add_argument("--ppo-seeds", type=int, default=1, help="agent runs, seeds 0 ..")
    parser.add_argument("--algo", nargs="+", default=["ppo"], choices=sorted(AGENTS),
                        help="the learned agents (recurrent-ppo: sb3-contrib's LSTM PPO, "
                             "for a disturbance that one epoch does not show)")
    parser.add_argument("--tuned-from", default=None, metavar="STUDY.json",
                        help="take the best constant retune and the oracle's actions from "
                             "an earlier study of the scenario (its --out file) instead of "
                             "tuning them again")
    parser.add_argument("--agent", action="append", default=[],
                        metavar="NAME=module.path:factory",
                        help="your own agent, an arm named NAME: factory(train_env) trains "
                             "on the training split's vector env (16 slots, same-step "
                             "autoreset) and returns policy(obs, k) -> actions (n, A)")
    parser.add_argument("--reward", default="attitude", choices=REWARDS,
                        help="the reward the agents train on (scoring uses the default)")
    parser.add_argument("--normalize", action="store_true",
                        help="PPO on VecNormalize (running obs and return scaling)")
    parser.add_argument("--episode-length", type=float, default=600.0)
    parser.add_argument("--bank", default="bank")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default=None)
    parser.add_argument("--headroom", default=None, metavar="FILE.json",
                        help="record the scenario's headroom entry in this file (the "
                             "leaderboard's docs/study/headroom.json)")
    args = parser.parse_args()
    clock = time.perf_counter()
    experiment = env_experiment(args.scenario, args.episode_length, 1.0)
    name = type(experiment).__module__.rsplit(".", 1)[-1]
    base = BASE[name]
    filters = [f for f in dict.fromkeys([*experiment.default_filters, base])]
    if not filter_entry(base).model:     # the textbook adaptive baseline, on base's model
        filters.append("sage-husa")
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
    earlier = tuned_actions(args.tuned_from) if args.tuned_from else {}
    start = time.perf_counter()
    if "constant" in earlier:
        action, history = earlier["constant"], []
    else:
        action, history = cross_entropy(make, train[:args.ce_episodes], args.ce_iterations,
                                        args.ce_population, args.reward)
    env = make(len(test), "test")
    trained_on = f", {args.reward} reward" if args.reward != "attitude" else ""
    best_constant = score(env, test, constant(action[0], len(test)))
    # the tuned actions' own reward: this run's, unless taken from --tuned-from
    ce_on = "" if "constant" in earlier else trained_on
    rows.append(summarise("constant retune (CE)" + ce_on, base, best_constant,
                          tuned[base], {"action": action[0].tolist(),
                                        "train_reward": history,
                                        "wall_s": time.perf_counter() - start}))
    env.close()
    arms = {f"{f} as tuned": tuned[f] for f in filters}
    arms["best constant"] = best_constant
    starts = segment_starts(experiment.scenario_config().schedule,
                            bank.get(train[0]).fine_start, experiment.filter_step,
                            episode_step_count(experiment.fine_duration,
                                               experiment.filter_step))
    oracle = None
    if starts:                     # the oracle: a constant retune per segment of the schedule
        start = time.perf_counter()
        if "oracle" in earlier:
            actions, history = earlier["oracle"], []
        else:
            actions, history = cross_entropy(
                make, train[:args.ce_episodes], args.oracle_iterations,
                args.oracle_population, args.reward, elite=max(3, args.oracle_population // 4),
                starts=starts, initial=np.tile(action, (len(starts) + 1, 1)))
        env = make(len(test), "test")
        oracle = score(env, test, piecewise(actions, starts, len(test)))
        env.close()
        oracle_on = "" if "oracle" in earlier else trained_on
        rows.append(summarise("oracle: constant per segment" + oracle_on, base, oracle,
                              tuned[base], {"actions": actions.tolist(),
                                            "segment_starts": starts,
                                            "train_reward": history,
                                            "wall_s": time.perf_counter() - start}))
    for spec in args.agent:               # users' agents: NAME=module.path:factory
        label, _, target = spec.partition("=")
        start = time.perf_counter()
        train_env = make(SLOTS, "train", autoreset_mode="SameStep", reward=args.reward)
        policy = load_agent(target)(train_env)
        trained = time.perf_counter() - start
        train_env.close()
        env = make(len(test), "test")
        arms[label] = score(env, test, policy)
        env.close()
        rows.append(summarise(label, base, arms[label], tuned[base],
                              {"agent": target, "wall_s": trained}))
    for algo in args.algo if args.ppo_steps > 0 else ():
        for seed in range(args.ppo_seeds):
            start = time.perf_counter()
            model, vec, curve = train_agent(algo, make, seed, args)
            trained = time.perf_counter() - start
            env = make(len(test), "test")
            arm = AGENTS[algo] + (", normalised" if args.normalize else "") + trained_on + (
                f", seed {seed}" if args.ppo_seeds > 1 else "")
            arms[arm] = score(env, test, agent_policy(model, vec, len(test), algo))
            rows.append(summarise(arm, base, arms[arm], tuned[base],
                                  {"algo": algo, "ppo_steps": args.ppo_steps,
                                   "ppo_seed": seed, "normalize": args.normalize,
                                   "wall_s": trained,
                                   "learning_curve": curve}))
            env.close()
            vec.close()
    out = {"scenario": args.scenario, "experiment": name, "episode_length_s":
           args.episode_length, "train_episodes": args.train, "test_episodes": args.test,
           "test_seeds": [test[0], test[-1]], "train_reward": args.reward,
           "ppo_seeds": args.ppo_seeds, "normalize": args.normalize, "bank_s": bank_s,
           "wall_s": time.perf_counter() - clock, "arguments": vars(args), "rows": rows}
    entry = None
    if oracle is not None:
        entry = headroom(args.scenario, tuned[base], best_constant, oracle,
                         {**arms, "oracle": oracle})
        out["headroom"] = entry
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    if entry is not None:
        if args.headroom:
            record_headroom(Path(args.headroom), entry)
        print_headroom(entry)
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
