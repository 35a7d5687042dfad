"""Gymnasium interface, built from the scenario's experiment (``scenarios.experiments``):
one episode is one alignment run (the coarse stage, if the experiment has one, then the
fine alignment); each step is one filter epoch. The observation holds only what the
filter knows; the action rescales the filter's noise tuning; the reward and ``info`` use
the truth.

Observation (float32, 16): normalised innovations e_i / sqrt(S_ii) (up to 3, clipped to
+-10); log10 of the attitude and bias covariance diagonal relative to its initial value
(up to 9: the experiment's attitude, gyro-drift and accelerometer-bias states, 003: 9,
002: 8; clipped to [-20, 5]); log10 of the current fading factors (3, zero where the
filter has fewer, the smallest three of 001's weights; clipped to [-2, 3]); elapsed fraction of the fine alignment (1).
Unused entries are zero.

Action (float32 in [-1, 1]): log-scale multipliers 10^(2 a) on the variances of the
gyro white noise, the accelerometer white noise and the measurement noise, and, for
fading-factor filters, 10^a on the fading-factor floor (tuned value 1). The zero action
runs the filter exactly as tuned.

Reward: minus the attitude error after the epoch,
sqrt((phi_E / 1')^2 + (phi_N / 1')^2 + (phi_U / 10')^2), capped at 100: level errors
count per arcminute, heading errors per 10 arcminutes.
"""
from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from aligngym.estimators.filters import UnknownFilter, filter_entry, make_filter
from aligngym.estimators.alignment import AlignmentRun
from aligngym.estimators.metrics import misalignment
from aligngym.models.units import arcmin
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios import campaign
from aligngym.scenarios.campaign import PreparedEpisode
from aligngym.scenarios.experiments import experiment_for

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

OBS_SIZE = 16
REWARD_SCALE = np.array([1.0, 1.0, 10.0]) * arcmin
REWARD_CAP = 100.0


class AlignmentEnv(gym.Env):
    """Alignment of the scenario's IMU by one estimator (see the module docstring).

    scenario: scenario name; estimator: filter name (``estimators.filters.FILTERS``);
    episode_length: fine-alignment duration, s; epoch_length: filter epoch, s;
    render_mode: None or "rgb_array"; video_path: with "rgb_array", write each
    episode's frames to this MP4 file; mistuning: variance multipliers applied to the
    filter's tuning before the agent acts ({"gyro_noise", "accel_noise", "measurement"}),
    to build a deliberately mistuned filter; cache_episodes: number of simulated episodes
    kept in memory by episode seed (repeated resets with the same seed skip MuJoCo; with
    more than 0, episodes are also shared with this process's other envs of the same
    experiment, ``SHARED_EPISODES`` of them; 0: no caching).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, scenario: str = "ship-sway-rotary", estimator: str = "kf",
                 episode_length: float = 600.0, epoch_length: float = 1.0,
                 render_mode: str | None = None, video_path: str | None = None,
                 mistuning: dict[str, float] | None = None, cache_episodes: int = 8,
                 render_size: tuple[int, int] = (240, 320)) -> None:
        try:
            filter_entry(estimator)
        except UnknownFilter as exc:
            raise ConfigError(str(exc)) from None
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode = {render_mode!r}; valid: None, 'rgb_array'")
        if not (episode_length > 0 and epoch_length > 0 and episode_length >= epoch_length):
            raise ConfigError("need episode_length >= epoch_length > 0 s, got "
                              f"{episode_length}, {epoch_length}")
        self.estimator, self.render_mode, self.video_path = estimator, render_mode, video_path
        self.experiment = experiment_for(scenario, fine_duration=episode_length,
                                         filter_step=epoch_length)
        self.config = self.experiment.scenario_config()
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
        self.action_space = spaces.Box(-1.0, 1.0, (4 if self._fading else 3,), np.float32)
        low = np.concatenate([np.full(3, -10.0), np.full(9, -20.0), np.full(3, -2.0), [0.0]])
        high = np.concatenate([np.full(3, 10.0), np.full(9, 5.0), np.full(3, 3.0), [1.0]])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32),
                                            dtype=np.float32)
        self._cache: OrderedDict[int, PreparedEpisode] = OrderedDict()
        self._cache_size = cache_episodes
        self._render_size = render_size
        self._scene = None
        self._run: AlignmentRun | None = None
        self._over = False
        self._frames: list[np.ndarray] = []

    # --- episode ------------------------------------------------------------------------
    def _prepare(self, episode_seed: int) -> PreparedEpisode:
        if episode_seed in self._cache:
            self._cache.move_to_end(episode_seed)
            return self._cache[episode_seed]
        key = (self.experiment, episode_seed)
        if self._cache_size > 0 and key in _SHARED:   # another env of this process has it
            _SHARED.move_to_end(key)
            episode = _SHARED[key]
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

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Options: "episode_seed" (int, else drawn from np_random), "start_error":
        "default" (the experiment's: the episode's own coarse alignment for 003, the
        large azimuth error for 002; "coarse" is the same), "random" (drawn from the
        filter's initial attitude sigma) or phi E, N, U in rad (3,)."""
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
        super().reset(seed=seed)
        episode_seed = int(chosen if chosen is not None
                           else self.np_random.integers(0, 2 ** 31 - 1))
        self._episode = self._prepare(episode_seed)
        start = options.get("start_error", "default")
        if isinstance(start, str):
            if start in ("default", "coarse"):
                start = self.experiment.episode_start(self._episode)
            elif start == "random":
                start = self.np_random.standard_normal(3) * self.experiment.attitude_sigma()
            else:
                raise ConfigError(f"start_error = {start!r}; valid: 'default', 'random' or "
                                  "3 angles in rad")
        self._start_error = _real_array(start, "start_error", "3 finite angles in rad (E, N, U)")
        if self._start_error.shape != (3,) or not np.all(np.isfinite(self._start_error)):
            raise ConfigError("start_error must be 3 finite angles in rad (E, N, U)")
        filt = make_filter(self.estimator, **self.experiment.filter_options())
        self._filter = filt
        self._run = AlignmentRun(filt, self.experiment.model(
            [self._episode], self._start_error, filter_entry(self.estimator).model))
        self._observed = self.experiment.observed_states(self._run.model.layout)
        self._episode_seed = episode_seed
        self._over = False
        self._frames = []
        if self.render_mode == "rgb_array" and self.video_path:
            self._frames.append(self.render())
        return self._observation(), {"episode_seed": episode_seed,
                                     "start_error_arcmin": self._start_error / arcmin}

    @property
    def episode_steps(self) -> int:
        """Steps (filter epochs) of an episode: episode_length / epoch_length."""
        return int(round(self.experiment.fine_duration / self.experiment.filter_step))

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
        a = _real_array(action, "action", f"{self.action_space.shape[0]} real numbers in [-1, 1]",
                        ValueError)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape} "
                             f"(log10 scales of Q_gyro, Q_accel, R{', floor' if self._fading else ''}"
                             f" in [-1, 1]), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        if self._fading:
            self._filter.adaptation.retune(floor=10.0 ** a[3])
        run = self._run
        mis = self._mistuning
        run.step(q_scale=(mis["gyro_noise"] * 10.0 ** (2 * a[0]),
                          mis["accel_noise"] * 10.0 ** (2 * a[1])),
                 r_scale=mis["measurement"] * 10.0 ** (2 * a[2]))
        k = run.k
        error = self._attitude_error()
        reward = -min(float(np.linalg.norm(error / REWARD_SCALE)), REWARD_CAP)
        diverged = bool(run.filt.health.diverged[0])
        terminated = diverged
        truncated = run.done and not diverged
        self._over = terminated or truncated
        info = {"error_arcmin": error / arcmin, "time_s": float(run.t[k] -
                                                                run.t[0]),
                "diverged": diverged}
        if self._over:
            result = run.result()
            analysed = campaign.analyse_run(self.estimator, "env", result, [self._episode],
                                            self.experiment)
            info["metrics"] = campaign.episode_metrics(analysed, 0, self.experiment,
                                                       self._episode.fine_start)
        if self.render_mode == "rgb_array" and self.video_path:
            self._frames.append(self.render())
            if self._over:
                self._write_video()
        return self._observation(), reward, terminated, truncated, info

    def _observation(self) -> np.ndarray:
        run, filt = self._run, self._filter
        obs = np.zeros(OBS_SIZE)
        if filt.innovation is not None:
            e = filt.innovation[0] / np.sqrt(np.diagonal(filt.S[0]))
            obs[0:min(3, e.size)] = e[:3]
        diag = np.diagonal(filt.P[0])
        diag0 = np.diagonal(run.P[0, 0])
        sub = self._observed
        with np.errstate(divide="ignore"):
            obs[3:3 + sub.size] = np.log10(np.maximum(diag[sub], 1e-300) / diag0[sub])
        if run.k > 0 and run.factors is not None and run.factors.shape[-1]:
            f = run.factors[0, run.k - 1]
            f = f[np.isfinite(f)]
            if f.size > 3:          # more than three (001's weights): the smallest three
                f = np.sort(f)[:3]
            obs[12:12 + f.size] = np.log10(np.maximum(f, 1e-3))
        obs[15] = run.k / run.epochs
        return np.clip(obs, self.observation_space.low, self.observation_space.high).astype(
            np.float32)

    def _attitude_error(self) -> np.ndarray:
        """The estimator's attitude error E, N, U (3,) rad at the current epoch."""
        k = self._run.k
        return misalignment(self._episode.C_s_n_true[k], self._run.C_s_n[0, k])

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
            run, k = self._run, self._run.k
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
             start_error: np.ndarray | str = "default", **env_kwargs) -> list[dict]:
    """Run the estimator passively (zero action) on the campaign's episode seeds and return
    the per-episode metrics table (the campaign's rows for the same seeds and start)."""
    from aligngym.scenarios.campaign import episode_seeds

    env = gym.make(env_id, estimator=estimator, **env_kwargs)
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    rows = []
    try:
        for s in episode_seeds(seed, episodes):
            env.reset(seed=s, options={"episode_seed": s, "start_error": start_error})
            while True:
                _, _, terminated, truncated, info = env.step(zero)
                if terminated or truncated:
                    break
            rows.append({"seed": s, "filter": estimator, **info["metrics"]})
    finally:
        env.close()
    return rows
