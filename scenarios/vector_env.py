"""The native vector env: N alignment episodes stepped through batched filters in one
process (``gym.make_vec(ENV_ID, num_envs=N)``; ``vectorization_mode="vector_entry_point"``
is the default for the aligngym ids).

All N slots share one batched filter (``env_core.EnvRun``), whenever they reset: each
slot's episode has its own epoch, and a slot that resets begins its new episode in the
filter while the others go on (a divergence or a reset_mask leaves the slots ending at
different steps without splitting the batch). Every slot's observations,
rewards, ends and infos are those of N single envs (``scenarios.env.AlignmentEnv``) in a
``SyncVectorEnv`` with the same seeds, bit for bit: a slot's episode seed is drawn from
its own generator (seeded with seed + i by ``reset(seed=seed)``), its reset options are
the same, and its filter computes as a batch of one would.

Autoreset: gymnasium 1.x's modes (``autoreset_mode``, an ``AutoresetMode`` or its
value): NEXT_STEP (the default: the step after an episode's end resets that slot,
ignoring its action, with reward 0), SAME_STEP (the ending step returns the next
episode's first observation, the last one in ``info["final_obs"]`` and its info in
``info["final_info"]``) or DISABLED (reset ended slots with
``reset(options={"reset_mask": ...})``). ``info`` is batched as
gymnasium's vector envs do (each key with its ``_key`` mask). No rendering.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from aligngym.models.units import arcmin
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.env_core import EnvCore, EnvRun


class AlignmentVectorEnv(EnvCore, VectorEnv):
    """num_envs alignment episodes of one scenario and estimator (see the module
    docstring); the other arguments are ``AlignmentEnv``'s (render_mode must be None)."""

    def __init__(self, num_envs: int = 1, scenario: str = "ship-sway-rotary",
                 estimator: str = "kf", episode_length: float = 600.0,
                 epoch_length: float = 1.0, mistuning: dict[str, float] | None = None,
                 cache_episodes: int = 8, settings: dict | None = None,
                 bank: str | Path | None = None, split: str | None = None,
                 split_episodes: int = 1000, reward: str = "attitude",
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 render_mode: str | None = None) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) \
                or num_envs < 1:
            raise ConfigError(f"num_envs = {num_envs!r}; valid: an integer >= 1")
        if render_mode is not None:
            raise ConfigError(f"render_mode = {render_mode!r}: the vector env does not "
                              "render; use vectorization_mode='sync' for frames")
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ConfigError(f"autoreset_mode = {autoreset_mode!r}; valid: " + ", ".join(
                m.value for m in AutoresetMode)) from None
        self._configure(scenario, estimator, episode_length, epoch_length, mistuning,
                        max(cache_episodes, 0), settings, bank, split, split_episodes,
                        reward)
        self.num_envs = int(num_envs)
        self.render_mode = None
        self.metadata = {**self.metadata, "render_modes": [], "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._slots: EnvRun | None = None     # slot i is the run's member i
        self._episode_seeds = np.full(self.num_envs, -1)
        self._obs = np.zeros((self.num_envs, *self.single_observation_space.shape),
                             np.float32)
        self._autoreset = np.zeros(self.num_envs, bool)

    # --- slots ----------------------------------------------------------------------------
    def _start(self, slots: list[int], seeds: list[int | None], options: dict,
               episode_seeds: list | None = None) -> list[dict]:
        """Begin a new episode in each slot (episode_seeds: one per slot, else the
        options'), in the shared filter; their infos."""
        begun = []
        for n, (i, seed) in enumerate(zip(slots, seeds)):
            if seed is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(seed)
            own = options if episode_seeds is None else {**options,
                                                          "episode_seed": episode_seeds[n]}
            begun.append(self._begin(own, self._rngs[i]))
        episodes = [episode for _, episode, _ in begun]
        starts = np.stack([start for _, _, start in begun])
        if self._slots is None or len(slots) == self.num_envs:
            self._slots = EnvRun(self, episodes, starts)
        else:
            self._slots.restart(slots, episodes, starts)
        obs = self._slots.observations()
        infos = []
        for i, (episode_seed, _, start) in zip(slots, begun):
            self._episode_seeds[i] = episode_seed
            self._obs[i] = obs[i]
            self._autoreset[i] = False
            infos.append({"episode_seed": episode_seed, "start_error_arcmin": start / arcmin})
        return infos

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict | None = None):
        """Reset every slot (seed: None, an int (slot i gets seed + i) or one per slot), or
        the slots of ``options["reset_mask"]`` (bool (num_envs,)); the other options are
        ``AlignmentEnv.reset``'s, applied to every slot reset, except that
        "episode_seed" may also give one seed per slot (a sequence of num_envs: slot i
        runs the i-th; SyncVectorEnv would pass the whole sequence to every env)."""
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        per_slot = options.get("episode_seed")
        if per_slot is not None and np.ndim(per_slot) == 1:
            if len(per_slot) != self.num_envs:
                raise ConfigError(f"episode_seed: {len(per_slot)} seeds for num_envs = "
                                  f"{self.num_envs}")
            per_slot = [int(s) if isinstance(s, (int, np.integer)) and not isinstance(
                s, bool) else s for s in per_slot]
            for s in per_slot:
                self._check_options({"episode_seed": s})
            options.pop("episode_seed")
        else:
            per_slot = None
        options = self._check_options(options)
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ConfigError(f"reset seeds: {len(seeds)} given for num_envs = "
                                  f"{self.num_envs}")
        if mask is None:
            slots = list(range(self.num_envs))
        else:
            mask = np.asarray(mask)
            if mask.shape != (self.num_envs,) or mask.dtype != bool or not mask.any():
                raise ConfigError(f"reset_mask must be a bool array of shape "
                                  f"({self.num_envs},) with a True value")
            slots = [int(i) for i in np.flatnonzero(mask)]
        infos: dict = {}
        chosen = None if per_slot is None else [per_slot[i] for i in slots]
        for i, info in zip(slots, self._start(slots, [seeds[i] for i in slots], options,
                                              chosen)):
            infos = self._add_info(infos, info, i)
        return self._obs.copy(), infos

    def step(self, actions):
        """One filter epoch per slot (actions (num_envs, A), clipped to [-1, 1]); slots
        ended at the previous step are reset instead in "next-step" mode."""
        if self._slots is None:
            raise RuntimeError("call reset() before step()")
        actions = self._checked_actions(actions, (self.num_envs,))
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, bool)
        truncated = np.zeros(self.num_envs, bool)
        slot_infos: list[dict] = [{} for _ in range(self.num_envs)]
        resetting = [i for i in range(self.num_envs) if self._autoreset[i]]
        if resetting and self.autoreset_mode == AutoresetMode.DISABLED:
            raise RuntimeError(f"slots {resetting} ended: reset them (reset_mask) before "
                               "step() in autoreset_mode 'disabled'")
        stepping = [i for i in range(self.num_envs) if i not in resetting]
        if stepping:
            # next-step mode: the ended slots go through the step with the zero action
            # (``EnvRun.step``), then begin their new episodes
            members = np.where(self._autoreset[:, None], 0.0, actions)
            obs, reward, term, trunc, infos = self._slots.step(members)
            for i in stepping:
                self._obs[i], rewards[i], terminated[i], truncated[i] = (
                    obs[i], reward[i], term[i], trunc[i])
                slot_infos[i] = infos[i]
        if self.autoreset_mode == AutoresetMode.NEXT_STEP and resetting:
            for i, info in zip(resetting, self._start(resetting, [None] * len(resetting), {})):
                slot_infos[i] = info
        ended = [i for i in stepping if terminated[i] or truncated[i]]
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended:
            finals = {i: {"final_obs": self._obs[i].copy(), "final_info": slot_infos[i]}
                      for i in ended}
            for i, info in zip(ended, self._start(ended, [None] * len(ended), {})):
                slot_infos[i] = (finals[i], info)
        infos: dict = {}
        for i in range(self.num_envs):
            if isinstance(slot_infos[i], tuple):      # same-step: the final, then the reset
                infos = self._add_info(infos, slot_infos[i][0], i)
                infos = self._add_info(infos, slot_infos[i][1], i)
            else:
                infos = self._add_info(infos, slot_infos[i], i)
        # same-step: the ended slots run their next episode already
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        self._autoreset = (terminated | truncated) & (not same_step)
        return self._obs.copy(), rewards, terminated, truncated, infos

    @property
    def episode_seeds(self) -> np.ndarray:
        """The episode seed each slot runs (num_envs,)."""
        return self._episode_seeds.copy()

    def close_extras(self, **kwargs) -> None:
        self._slots = None
