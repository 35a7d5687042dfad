"""Gymnasium interface, built from the scenario's experiment (``scenarios.experiments``):
one episode is one alignment run (the coarse stage, if the experiment has one, then the
fine alignment); each step is one filter epoch. The observation holds only what the
filter knows; the action rescales the filter's noise tuning; the reward and ``info`` use
the truth. The observation, the action and the reward, and what this env shares with the
vector env: ``scenarios.env_core``.
"""
from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from aligngym.estimators.alignment import AlignmentRun
from aligngym.models.units import arcmin
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.env_core import EnvCore, EnvRun


class AlignmentEnv(EnvCore, gym.Env):
    """Alignment of the scenario's IMU by one estimator (see the module docstring and
    ``scenarios.env_core``'s).

    scenario: scenario name or .toml path (any file in ``scenarios/data/``: one that
    names its experiment runs its default setup, a ``*-paper`` file its experiment's
    paper setup, as ``bench EXPERIMENT --setup paper``); estimator: filter name
    (``estimators.catalogue.FILTERS``); episode_length: fine-alignment duration, s;
    epoch_length: filter epoch, s; render_mode: None or "rgb_array"; video_path: with
    "rgb_array", write each episode's frames to this MP4 file; mistuning: variance
    multipliers applied to the filter's tuning before the agent acts ({"gyro_noise",
    "accel_noise", "measurement"}), to build a deliberately mistuned filter;
    cache_episodes: number of simulated episodes kept in memory by episode seed
    (repeated resets with the same seed skip MuJoCo; with more than 0, episodes are also
    shared with this process's other envs of the same experiment,
    ``env_core.SHARED_EPISODES`` of them; 0: no caching); settings: the experiment's
    other settings ({name: value}, as ``bench --set``; e.g. a shorter coarse stage);
    bank: an episode-bank directory
    (``scenarios.bank``: episodes are loaded from it, or simulated once and stored);
    split: "train", "validation" or "test" (episodes drawn among the split's first
    split_episodes seeds; an episode_seed of another split is refused); None: any seed;
    reward: one of ``env_core.REWARDS`` (see that module's docstring).
    """

    def __init__(self, scenario: str = "ship-sway-rotary", estimator: str = "kf",
                 episode_length: float = 600.0, epoch_length: float = 1.0,
                 render_mode: str | None = None, video_path: str | None = None,
                 mistuning: dict[str, float] | None = None, cache_episodes: int = 8,
                 render_size: tuple[int, int] = (240, 320), settings: dict | None = None,
                 bank: str | Path | None = None, split: str | None = None,
                 split_episodes: int = 1000, reward: str = "attitude") -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode = {render_mode!r}; valid: None, 'rgb_array'")
        self._configure(scenario, estimator, episode_length, epoch_length, mistuning,
                        cache_episodes, settings, bank, split, split_episodes, reward)
        self.render_mode, self.video_path = render_mode, video_path
        self.action_space = self.single_action_space
        self.observation_space = self.single_observation_space
        self._render_size = render_size
        self._scene = None
        self._slots: EnvRun | None = None
        self._run: AlignmentRun | None = None
        self._over = False
        self._frames: list[np.ndarray] = []

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Options: "episode_seed" (int, else drawn from np_random), "start_error":
        "default" (the experiment's: the episode's own coarse alignment for 003, the
        large azimuth error for 002; "coarse" is the same), "random" (drawn from the
        filter's initial attitude sigma) or phi E, N, U in rad (3,)."""
        options = self._check_options(options)
        super().reset(seed=seed)
        episode_seed, self._episode, self._start_error = self._begin(options, self.np_random)
        self._slots = EnvRun(self, [self._episode], self._start_error[None])
        self._run = self._slots.run
        self._episode_seed = episode_seed
        self._over = False
        self._frames = []
        if self.render_mode == "rgb_array" and self.video_path:
            self._frames.append(self.render())
        return self._slots.observations()[0], {
            "episode_seed": episode_seed, "start_error_arcmin": self._start_error / arcmin}

    def step(self, action):
        """One filter epoch with the action's tuning. Actions outside [-1, 1] are
        clipped to it; a wrong shape or a non-finite value raises ValueError. The episode
        ends with terminated = True when the filter diverges, or with truncated = True at
        its fixed length (episode_length / epoch_length steps); step() after the end
        raises RuntimeError until reset()."""
        if self._run is None:
            raise RuntimeError("call reset() before step()")
        if self._over:
            raise RuntimeError("the episode is over; call reset() before step()")
        a = self._checked_actions(action, ())
        obs, reward, terminated, truncated, infos = self._slots.step(a[None])
        terminated, truncated = bool(terminated[0]), bool(truncated[0])
        self._over = terminated or truncated
        if self.render_mode == "rgb_array" and self.video_path:
            self._frames.append(self.render())
            if self._over:
                self._write_video()
        return obs[0], float(reward[0]), terminated, truncated, infos[0]

    def _attitude_error(self) -> np.ndarray:
        """The estimator's attitude error E, N, U (3,) rad at the current epoch."""
        return self._slots.attitude_errors()[0]

    @property
    def alignment_start_s(self) -> float:
        """Scenario time (s) of the fine alignment's first epoch in this episode."""
        if self._run is None:
            raise RuntimeError("alignment_start_s before reset()")
        t = getattr(self._episode, "t", None)
        return float(t[0] if t is not None else self._run.t[0])

    # --- rendering ----------------------------------------------------------------------
    def render(self):
        """The scene at the current epoch (``scenarios.render``: the carrier followed by
        the camera, the IMU's close-up, time, attitude and the estimator's errors), or
        None without render_mode "rgb_array"."""
        if self.render_mode != "rgb_array":
            return None
        from aligngym.scenarios.render import SceneRenderer, error_line

        seed = getattr(self, "_episode_seed", 0)
        if self._scene is None or self._scene.seed != seed:    # the episode's own motion
            self.close()
            self._scene = SceneRenderer(self.config, seed=seed, size=self._render_size)
        lines = []
        t = 0.0
        if self._run is not None:
            run, k = self._run, int(self._run.k[0])
            t = self.alignment_start_s + float(run.t[k] - run.t[0])
            error = self._attitude_error() / arcmin
            lines = [error_line(self.estimator, error)]
        return self._scene.frame(min(t, self._scene.duration), lines)

    def _write_video(self) -> None:
        import imageio.v2 as imageio

        path = Path(self.video_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        from aligngym.scenarios.atomic import atomic_path
        with atomic_path(path, own_directory=True) as tmp:
            imageio.mimwrite(tmp, self._frames, fps=self.metadata["render_fps"],
                             macro_block_size=8)
        self._frames = []

    def close(self) -> None:
        if self._scene is not None:
            self._scene.close()
            self._scene = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_scene"] = None
        return state


def evaluate(env_id: str, estimator: str, episodes: int, seed: int = 0,
             start_error: np.ndarray | str = "default", split: str | None = None,
             **env_kwargs) -> list[dict]:
    """Run the estimator passively (zero action) on the campaign's episode seeds and return
    the per-episode metrics table (the campaign's rows for the same seeds and start);
    with split ("test", say), on that split's first episodes instead (campaign seeds
    below 1600 are training seeds: score an agent on "test"). env_id: any aligngym id
    (``aligngym/<Scenario>-v1`` of every shipped scenario, ``*-paper`` ones included, or
    ``aligngym/Alignment-v1`` with scenario=NAME or a .toml path in env_kwargs)."""
    from aligngym.scenarios.bank import split_seeds
    from aligngym.scenarios.campaign import episode_seeds

    seeds = split_seeds(split, episodes) if split else episode_seeds(seed, episodes)
    env = gym.make(env_id, estimator=estimator, split=split, **env_kwargs)
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    rows = []
    try:
        for s in seeds:
            env.reset(seed=s, options={"episode_seed": s, "start_error": start_error})
            while True:
                _, _, terminated, truncated, info = env.step(zero)
                if terminated or truncated:
                    break
            rows.append({"seed": s, "filter": estimator, **info["metrics"]})
    finally:
        env.close()
    return rows
