"""What the single env (``scenarios.env``) and the vector env (``scenarios.vector_env``)
share: the observation, action and reward definitions, the env core (``EnvCore``: the
experiment, the spaces, the mistuning, the episode cache and bank, the seed split, the
reset options, the reward) and the batched filter run of the slots' episodes, each at its
own epoch (``EnvRun``: its step, its restarts and its observations).

Observation (float32, 20): the normalised innovations e_i / sqrt(S_ii), all of the
measurement (``INNOVATIONS``, 7 slots: 001's position, velocity and GPS heading, 004's
velocity and position, 3 for 000 and 003, 2 for 002; a missing component is 0; clipped
to +-10); log10 of the attitude and bias covariance diagonal relative to its initial
value (``COVARIANCE``, up to 9: the experiment's attitude, gyro-drift and
accelerometer-bias states, 003: 9, 002: 8; clipped to [-20, 5]); log10 of the current
fading factors (``FACTORS``, 3, zero where the filter has fewer, the smallest three of
001's weights; clipped to [-2, 3]); the elapsed fraction of the fine alignment
(``ELAPSED``). Unused entries are zero.

Action (float32 in [-1, 1]): log-scale multipliers 10^(2 a) on the variances of the
gyro white noise, the accelerometer white noise and the measurement noise, and, for
fading-factor filters, 10^a on the fading-factor floor (tuned value 1). The zero action
runs the filter exactly as tuned.

Reward (``reward``, one of ``REWARDS``): "attitude" (the default) is minus the attitude
error after the epoch, e = sqrt((phi_E / 1')^2 + (phi_N / 1')^2 + (phi_U / 10')^2),
capped at 100: level errors count per arcminute, heading errors per 10 arcminutes;
"log" is -log10(1 + e) (every decade of error counts alike, no cap); "final" is 0 until
the episode's last step, which gets -min(e, 100) times the episode's steps (the same
scale as "attitude" summed; only where the filter ends counts). A diverged episode's
last step is also charged the worst reward (-100, or -log10(101)) for each epoch it did
not run, so that ending early never pays.
"""
from __future__ import annotations

import os
from collections import OrderedDict
from pathlib import Path

import numpy as np
from gymnasium import spaces

from aligngym.estimators.adaptation import PolicyTuning
from aligngym.estimators.alignment import AlignmentRun
from aligngym.estimators.catalogue import UnknownFilter, filter_entry, make_filter
from aligngym.estimators.filters import UpdateReport
from aligngym.estimators.metrics import misalignment
from aligngym.estimators.model import at_epoch, whole_steps
from aligngym.models.units import arcmin
from aligngym.scenarios.bank import SPLITS, EpisodeBank, check_seed_in_split, check_split
from aligngym.scenarios.config import ConfigError, SettingError
from aligngym.scenarios import campaign
from aligngym.scenarios.campaign import PreparedEpisode
from aligngym.scenarios.experiments import env_experiment

SHARED_EPISODES = 16
"""Prepared episodes kept per process across env instances (vectorised envs and repeated
makes of one scenario simulate each (experiment, seed) once); read-only."""
_SHARED: OrderedDict = OrderedDict()

RESET_OPTIONS = ("episode_seed", "start_error")
"""The keys ``reset(options=...)`` takes."""


def _real_array(value, name: str, expected: str, error: type = ConfigError) -> np.ndarray:
    """value as a float array; complex, boolean, string or object values are refused (a
    complex number's imaginary part is not dropped) with one line naming ``name``."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise error(f"{name} must be {expected}, got {array.dtype} values")
    return array.astype(float)


def _scenario_file(scenario):
    """The scenario file (``config.load_scenario``) of a shipped name or a .toml path;
    anything else is one line naming ``scenario`` and what it takes."""
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.registry import scenario_names
    if isinstance(scenario, bool) or not isinstance(scenario, (str, os.PathLike)) \
            or not str(scenario):
        raise ConfigError(f"scenario = {scenario!r}; valid: a shipped name ("
                          + ", ".join(scenario_names()) + ") or a .toml path")
    return load_scenario(scenario)


def _setup_settings(config, settings: dict | None) -> dict | None:
    """settings, checked for a file that names no experiment but is a named setup's own
    (a ``*-paper`` file runs its experiment's paper setup, ``experiments.setup_for``):
    its "setup" key may only repeat that setup (dropped); another is one line."""
    if config.experiment or not isinstance(settings, dict) or "setup" not in settings:
        return settings
    from aligngym.scenarios.experiments import setup_for
    named = setup_for(config.name)
    if named is None:              # experiment_for names the missing experiment key
        return settings
    if settings["setup"] != named[1]:
        raise ConfigError(f"settings setup = {settings['setup']!r}: {config.name} is "
                          f"{named[0]}'s {named[1]!r} setup; valid: {named[1]!r}")
    return {k: v for k, v in settings.items() if k != "setup"}


INNOVATIONS = slice(0, 7)
COVARIANCE = slice(7, 16)
FACTORS = slice(16, 19)
ELAPSED = 19
OBS_SIZE = 20
REWARD_SCALE = np.array([1.0, 1.0, 10.0]) * arcmin
REWARD_CAP = 100.0
REWARDS = ("attitude", "log", "final")


def episode_step_count(episode_length: float, epoch_length: float) -> int:
    """Steps (filter epochs) of an episode: the whole epochs of epoch_length s within
    episode_length s (``estimators.model.whole_steps``, the count the filter models cut
    too: 5 s in 0.3-s epochs is 16 steps, to 4.8 s). The one count the env's
    ``episode_steps`` and its truncation use (single and vector)."""
    return whole_steps(episode_length, epoch_length)


class EnvCore:
    """What the single and the vector env share: the experiment, the spaces, the
    mistuning, the episode cache and bank, the seed split and the reset options."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def _configure(self, scenario: str, estimator: str, episode_length: float,
                   epoch_length: float, mistuning: dict[str, float] | None,
                   cache_episodes: int, settings: dict | None, bank: str | Path | None,
                   split: str | None, split_episodes: int, reward: str) -> None:
        try:
            filter_entry(estimator)
        except UnknownFilter as exc:
            raise ConfigError(str(exc)) from None
        if reward not in REWARDS:
            raise ConfigError(f"reward = {reward!r}; valid: " + ", ".join(REWARDS))
        self.reward = reward
        self.estimator = estimator
        config = _scenario_file(scenario)
        labels = {"fine_duration": "episode_length", "filter_step": "epoch_length"}
        try:             # the settings checked where the experiment is made, named as given
            self.experiment = env_experiment(scenario, episode_length, epoch_length,
                                             _setup_settings(config, settings), config=config)
            self.config = self.experiment.scenario_config()
        except SettingError as exc:
            raise exc.as_written(lambda name: labels.get(name, f"settings[{name!r}]")) from None
        if not (episode_length is not None and episode_length >= epoch_length):
            raise ConfigError("need episode_length >= epoch_length > 0 s, got "
                              f"{episode_length}, {epoch_length}")
        self.experiment.check_filters([estimator])
        factors = {"gyro_noise": 1.0, "accel_noise": 1.0, "measurement": 1.0,
                   **(mistuning or {})}
        unknown = set(factors) - {"gyro_noise", "accel_noise", "measurement"}
        if unknown:
            raise ConfigError(f"mistuning key {sorted(unknown)[0]!r}; valid: gyro_noise, "
                              "accel_noise, measurement")
        bad = [k for k, v in factors.items() if not (np.isfinite(v) and v > 0)]
        if bad:
            raise ConfigError(f"mistuning {bad[0]!r} = {factors[bad[0]]} must be > 0")
        self._mistuning = factors
        self._fading = filter_entry(estimator).fading
        self.single_action_space = spaces.Box(-1.0, 1.0, (4 if self._fading else 3,),
                                              np.float32)
        width = lambda part: len(range(OBS_SIZE)[part])  # noqa: E731
        low = np.concatenate([np.full(width(INNOVATIONS), -10.0),
                              np.full(width(COVARIANCE), -20.0),
                              np.full(width(FACTORS), -2.0), [0.0]])
        high = np.concatenate([np.full(width(INNOVATIONS), 10.0),
                               np.full(width(COVARIANCE), 5.0),
                               np.full(width(FACTORS), 3.0), [1.0]])
        self.single_observation_space = spaces.Box(low.astype(np.float32),
                                                   high.astype(np.float32), dtype=np.float32)
        self._cache: OrderedDict[int, PreparedEpisode] = OrderedDict()
        self._cache_size = cache_episodes
        self._bank = None if bank is None else EpisodeBank(bank, self.experiment)
        if split is not None:
            lo, hi = check_split(split)
            if not (isinstance(split_episodes, (int, np.integer)) and 0 < split_episodes
                    <= hi - lo):
                raise ConfigError(f"split_episodes = {split_episodes!r}; valid: 1 to {hi - lo}")
        self.split, self.split_episodes = split, int(split_episodes)

    # --- episodes -----------------------------------------------------------------------
    def _prepare(self, episode_seed: int) -> PreparedEpisode:
        """The prepared episode of this seed: from this env's cache, this process's other
        envs, the bank, or a simulation."""
        if episode_seed in self._cache:
            self._cache.move_to_end(episode_seed)
            return self._cache[episode_seed]
        key = (self.experiment, episode_seed)
        if self._cache_size > 0 and key in _SHARED:   # another env of this process has it
            _SHARED.move_to_end(key)
            episode = _SHARED[key]
        else:
            if self._bank is not None:
                episode = self._bank.get(episode_seed, config=self.config)
            else:
                episode = self.experiment.prepare_episode(episode_seed, config=self.config)
            if self._cache_size > 0:
                _SHARED[key] = episode
                while len(_SHARED) > SHARED_EPISODES:
                    _SHARED.popitem(last=False)
        if self._cache_size > 0:
            self._cache[episode_seed] = episode
            while len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return episode

    @staticmethod
    def _check_options(options) -> dict:
        options = {} if options is None else options
        if not isinstance(options, dict):
            raise ConfigError(f"reset options must be a dict, got {type(options).__name__}")
        unknown = sorted(set(options) - set(RESET_OPTIONS), key=str)
        if unknown:
            raise ConfigError(f"reset option {unknown[0]!r} is unknown; valid: "
                              + ", ".join(RESET_OPTIONS))
        chosen = options.get("episode_seed")
        if chosen is not None and (isinstance(chosen, bool) or not isinstance(
                chosen, (int, np.integer)) or chosen < 0):
            raise ConfigError(f"episode_seed must be an integer >= 0, got {chosen!r}")
        return options

    def _begin(self, options: dict, rng: np.random.Generator
               ) -> tuple[int, PreparedEpisode, np.ndarray]:
        """The episode seed (the option's, else drawn from rng: within the split's first
        split_episodes with a split), the prepared episode and the start error (3,) rad."""
        chosen = options.get("episode_seed")
        if chosen is not None:
            episode_seed = int(chosen)
            if self.split is not None:
                check_seed_in_split(episode_seed, self.split)
        elif self.split is None:
            episode_seed = int(rng.integers(0, 2 ** 31 - 1))
        else:
            episode_seed = SPLITS[self.split][0] + int(rng.integers(0, self.split_episodes))
        episode = self._prepare(episode_seed)
        start = options.get("start_error", "default")
        if isinstance(start, str):
            if start in ("default", "coarse"):
                start = self.experiment.episode_start(episode)
            elif start == "random":
                start = rng.standard_normal(3) * self.experiment.attitude_sigma()
            else:
                raise ConfigError(f"start_error = {start!r}; valid: 'default', 'random' or "
                                  "3 angles in rad")
        start = _real_array(start, "start_error", "3 finite angles in rad (E, N, U)")
        if start.shape != (3,) or not np.all(np.isfinite(start)):
            raise ConfigError("start_error must be 3 finite angles in rad (E, N, U)")
        return episode_seed, episode, start

    def rewards(self, errors: np.ndarray, over: np.ndarray, diverged: np.ndarray,
                remaining: np.ndarray) -> np.ndarray:
        """The reward (see the module docstring) of attitude errors (B, 3) rad; over (B,):
        the episodes that end at this step; diverged (B,): those ending by divergence,
        which are charged the worst reward for each of their remaining epochs (B,) (so
        that ending early never pays)."""
        e = np.linalg.norm(errors / REWARD_SCALE, axis=-1)
        if self.reward == "log":
            worst, reward = -np.log10(1.0 + REWARD_CAP), -np.log10(1.0 + e)
        else:
            worst, reward = -REWARD_CAP, -np.minimum(e, REWARD_CAP)
            if self.reward == "final":
                reward = np.where(over, reward * self.episode_steps, 0.0)
        return np.where(diverged, reward + worst * remaining, reward)

    @property
    def episode_steps(self) -> int:
        """Steps (filter epochs) of an episode: ``episode_step_count`` of
        episode_length and epoch_length; the episode is truncated after them."""
        return episode_step_count(self.experiment.fine_duration, self.experiment.filter_step)

    def _checked_actions(self, actions, batch: tuple[int, ...]) -> np.ndarray:
        """actions (batch + action shape) as floats clipped to [-1, 1]; a wrong shape or
        a non-finite value raises ValueError."""
        shape = batch + self.single_action_space.shape
        a = _real_array(actions, "action", f"{self.single_action_space.shape[0]} real "
                        "numbers in [-1, 1]", ValueError)
        if a.shape != shape:
            raise ValueError(f"action must have shape {shape} (log10 scales of Q_gyro, "
                             f"Q_accel, R{', floor' if self._fading else ''} in [-1, 1]), "
                             f"got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a.tolist()}")
        return np.clip(a, -1.0, 1.0)


class EnvRun:
    """The episodes of the env's slots, run by one batched filter (B members): the single
    env's one, the vector env's num_envs. The run is staggered (each member at its own
    epoch): ``restart`` begins new episodes in some members while the others go on, so
    slots that reset at different steps still share the filter. Every member's numbers
    are those of a run of its episode alone."""

    def __init__(self, env: EnvCore, episodes: list[PreparedEpisode], starts: np.ndarray
                 ) -> None:
        self.env, self.episodes = env, list(episodes)
        self.run = self._run(self.episodes, starts)
        self.observed = env.experiment.observed_states(self.run.model.layout)
        self.report: UpdateReport | None = None
        """The last epoch's update (``GaussianFilter.update``); None before the first."""
        self.ended = np.zeros(self.run.batch, bool)
        """Members whose episode has ended (their metrics given once)."""
        self.steps = env.episode_steps
        """Steps after which the members are truncated (``episode_step_count``)."""
        if self.run.epochs < self.steps:       # the prepared data hold fewer epochs
            experiment = env.experiment
            raise ConfigError(f"the episodes hold {self.run.epochs} epochs of "
                              f"epoch_length = {experiment.filter_step:g} s, fewer than the "
                              f"{self.steps} steps of episode_length = "
                              f"{experiment.fine_duration:g} s")

    def _run(self, episodes: list[PreparedEpisode], starts: np.ndarray) -> AlignmentRun:
        experiment, estimator = self.env.experiment, self.env.estimator
        return AlignmentRun(make_filter(estimator, **experiment.filter_options()),
                            experiment.model(episodes, starts, filter_entry(estimator).model),
                            staggered=True)

    def restart(self, members: list[int], episodes: list[PreparedEpisode],
                starts: np.ndarray) -> None:
        """New episodes (with their start errors (M, 3) rad) in the members (indices)."""
        self.run.restart(np.asarray(members, int), self._run(episodes, starts))
        for b, episode in zip(members, episodes):
            self.episodes[b] = episode
        self.ended[members] = False

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                 np.ndarray, list[dict]]:
        """One filter epoch with each member's action (B, A), clipped already. Returns
        observations (B, OBS_SIZE), rewards, terminated, truncated (B,) and the infos.
        A member whose episode has ended (waiting for its reset) goes on through its
        data (through its last epoch again at the data's end), its outputs meaningless,
        until ``restart``."""
        env, run = self.env, self.run
        if self.ended.any():
            run.k = np.where(self.ended, np.minimum(run.k, run.epochs - 1), run.k)
        tuning = PolicyTuning(floor=10.0 ** actions[:, 3]) if env._fading else None
        mis = env._mistuning
        self.report = run.step(q_scale=(mis["gyro_noise"] * 10.0 ** (2 * actions[:, 0]),
                                        mis["accel_noise"] * 10.0 ** (2 * actions[:, 1])),
                               r_scale=mis["measurement"] * 10.0 ** (2 * actions[:, 2]),
                               tuning=tuning)
        errors = self.attitude_errors()
        diverged = run.diverged
        terminated = diverged
        truncated = (run.k >= self.steps) & ~diverged
        over = (terminated | truncated) & ~self.ended     # ending at this step
        rewards = env.rewards(errors, terminated | truncated, terminated & over,
                              self.steps - run.k)
        self.ended |= over
        time_s = run.t[run.k] - run.t[0]
        infos = [{"error_arcmin": errors[b] / arcmin, "time_s": float(time_s[b]),
                  "diverged": bool(diverged[b])} for b in range(run.batch)]
        ending = np.flatnonzero(over)
        for k in np.unique(run.k[ending]):      # the members ending together, analysed once
            members = ending[run.k[ending] == k]
            episodes = [self.episodes[b] for b in members]
            analysed = campaign.analyse_run(env.estimator, "env", run.result(members),
                                            episodes, env.experiment)
            for i, b in enumerate(members):
                infos[b]["metrics"] = campaign.episode_metrics(
                    analysed, i, env.experiment, episodes[i].fine_start)
        return self.observations(), rewards, terminated, truncated, infos

    def observations(self) -> np.ndarray:
        """What each member's filter knows (see the module docstring), (B, OBS_SIZE)
        float32."""
        run, space = self.run, self.env.single_observation_space
        obs = np.zeros((run.batch, OBS_SIZE))
        first = INNOVATIONS.start
        report = self.report
        reported = run.k > 0           # members with an update of their episode: its rows
        if report is not None and reported.any():
            with np.errstate(divide="ignore", invalid="ignore"):
                e = report.innovation / np.sqrt(np.diagonal(report.S, axis1=-2, axis2=-1))
            m = min(e.shape[-1], INNOVATIONS.stop - first)
            used = report.valid & reported[:, None]
            obs[:, first:first + m] = np.where(used, e, 0.0)[:, :m]
        sub = self.observed
        k = run.k
        diag = np.diagonal(at_epoch(run.P, k), axis1=-2, axis2=-1)[:, sub]  # after feedback
        diag0 = np.diagonal(run.P[:, 0], axis1=-2, axis2=-1)[:, sub]
        first = COVARIANCE.start
        with np.errstate(divide="ignore"):
            obs[:, first:first + sub.size] = np.log10(np.maximum(diag, 1e-300) / diag0)
        if run.factors is not None and run.factors.shape[-1]:
            for b in np.flatnonzero(k > 0):
                f = run.factors[b, k[b] - 1]
                f = f[np.isfinite(f)]
                if f.size > 3:      # more than three (001's weights): the smallest three
                    f = np.sort(f)[:3]
                obs[b, FACTORS.start:FACTORS.start + f.size] = np.log10(np.maximum(f, 1e-3))
        obs[:, ELAPSED] = k / self.steps
        return np.clip(obs, space.low, space.high).astype(np.float32)

    def attitude_errors(self) -> np.ndarray:
        """Each member's attitude error E, N, U (B, 3) rad at its current epoch."""
        k = self.run.k
        C_true = np.stack([e.C_s_n_true[k[b]] for b, e in enumerate(self.episodes)])
        return misalignment(C_true, at_epoch(self.run.C_s_n, k))
