"""The native vector env (batched filters in one process) against N single envs in
gymnasium's SyncVectorEnv, the episode bank against a fresh simulation, and the seed
splits."""
import numpy as np
import gymnasium as gym
import pytest
from gymnasium.vector import AutoresetMode

import aligngym  # noqa: F401  (registers the ids)
from aligngym.scenarios.bank import SPLITS, EpisodeBank, split_of, split_seeds
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.env_core import ELAPSED, OBS_SIZE
from aligngym.scenarios.experiments import experiment_for
from aligngym.scenarios.vector_env import AlignmentVectorEnv

SHIP_ID = "aligngym/ShipSwayRotary-v1"
# A short coarse stage (the env's settings): 20 s of physics before the fine start.
QUICK = {"episode_length": 12.0, "estimator": "imakf",
         "settings": {"coarse_duration": 20.0, "t_k1": 8.0, "t_k2": 20.0}}


def assert_same(a, b, path="info"):
    """Equal, bit for bit (NaN equal to NaN), apart from the compute timings."""
    if isinstance(a, dict):
        assert set(a) == set(b), (path, set(a) ^ set(b))
        for key in a:
            if "ms_per_epoch" not in key:
                assert_same(a[key], b[key], f"{path}[{key!r}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    else:
        assert np.array_equal(a, b, equal_nan=np.asarray(a).dtype.kind == "f"), (path, a, b)


def play(env, steps, seed, resets=(), slot=None):
    """Reset with seed, then step with seeded random actions; at the steps in resets,
    reset one slot alone (slot 0, or the slot given per step in ``slot``; its new
    episode runs in the shared filter beside the others, at another epoch). Returns
    every output."""
    out = [env.reset(seed=seed)]
    rng = np.random.default_rng(seed)
    for k in range(steps):
        if k in resets:
            mask = np.zeros(env.num_envs, bool)
            mask[(slot or {}).get(k, 0)] = True
            out.append(env.reset(options={"reset_mask": mask}))
        out.append(env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)))
    env.close()
    return out


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_env_equals_single_envs_bit_for_bit(mode):
    """Three slots over about three episodes each, slot 0 reset alone mid-episode (so the
    slots end at different steps and run in different cohorts), in both autoreset modes:
    the same observations, rewards, ends and infos as three single envs."""
    native = gym.make_vec(SHIP_ID, num_envs=3, autoreset_mode=mode, **QUICK)
    sync = gym.make_vec(SHIP_ID, num_envs=3, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **QUICK)
    a, b = play(native, 34, seed=7, resets=(5,)), play(sync, 34, seed=7, resets=(5,))
    ends = 0
    for x, y in zip(a, b):
        assert len(x) == len(y)
        for u, v in zip(x, y):
            assert_same(u, v)
        if len(x) == 5:
            ends += int(np.sum(x[2] | x[3]))
    assert ends >= 6          # episodes ended (and were reset) along the way


def test_make_vec_defaults_to_the_native_env_on_every_id():
    from aligngym.envs import ENV_IDS
    for env_id in ENV_IDS:
        assert gym.spec(env_id).vector_entry_point.endswith("AlignmentVectorEnv")
    envs = gym.make_vec(SHIP_ID, num_envs=2, **QUICK)
    assert isinstance(envs.unwrapped, AlignmentVectorEnv)
    obs, info = envs.reset(seed=1)
    assert obs.shape == (2, OBS_SIZE) and info["_episode_seed"].all()
    envs.close()


def test_next_step_autoreset_semantics():
    """The step after an episode's end resets that slot: its action ignored, reward 0,
    neither terminated nor truncated, a new episode seed in info; the other slots step."""
    env = AlignmentVectorEnv(2, scenario="ship-sway-rotary", **QUICK)
    _, info = env.reset(seed=3)
    first = info["episode_seed"].copy()
    steps = env.episode_steps
    zero = np.zeros(env.action_space.shape, np.float32)
    for _ in range(steps - 1):
        _, _, terminated, truncated, _ = env.step(zero)
        assert not (terminated | truncated).any()
    _, _, terminated, truncated, info = env.step(zero)
    assert truncated.all() and not terminated.any()
    assert info["_metrics"].all() and np.isfinite(info["metrics"]["final_phi_U_arcmin"]).all()
    obs, reward, terminated, truncated, info = env.step(
        np.full(env.action_space.shape, 5.0, np.float32))
    assert np.array_equal(reward, [0.0, 0.0]) and not (terminated | truncated).any()
    assert info["_episode_seed"].all() and not np.array_equal(info["episode_seed"], first)
    assert np.all(obs[:, ELAPSED] == 0.0)           # the first epoch of the new episodes
    env.close()


def through_one_episode(mode):
    """Two slots in this autoreset mode, reset with seed 3 and stepped through one
    episode with the zero action: the env, the zero action and the last step's output."""
    env = AlignmentVectorEnv(2, scenario="ship-sway-rotary", autoreset_mode=mode, **QUICK)
    env.reset(seed=3)
    zero = np.zeros(env.action_space.shape, np.float32)
    for _ in range(env.episode_steps):
        out = env.step(zero)
    return env, zero, out


def test_same_step_autoreset_keeps_the_final_observation():
    env, _, (obs, _, terminated, truncated, info) = through_one_episode(AutoresetMode.SAME_STEP)
    assert truncated.all()
    assert info["_final_obs"].all() and info["final_obs"][0][ELAPSED] == 1.0   # last epoch
    assert np.all(obs[:, ELAPSED] == 0.0)                      # already the next episodes
    assert "metrics" in info["final_info"] and info["_episode_seed"].all()
    env.close()


def test_disabled_autoreset_needs_a_reset_mask():
    env, zero, _ = through_one_episode(AutoresetMode.DISABLED)
    with pytest.raises(RuntimeError, match="reset_mask"):
        env.step(zero)
    env.reset(options={"reset_mask": np.array([True, True])})
    env.step(zero)
    env.close()


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 0}, "num_envs"), ({"num_envs": 2, "render_mode": "rgb_array"}, "render"),
    ({"num_envs": 2, "autoreset_mode": "Later"}, "autoreset_mode"),
    ({"num_envs": 2, "settings": {"no_such_setting": 1}}, "settings"),
    ({"num_envs": 2, "settings": {"fine_duration": 5.0}}, "episode_length"),
    ({"num_envs": 2, "split": "holdout"}, "split"),
    ({"num_envs": 2, "split": "train", "split_episodes": 0}, "split_episodes")])
def test_vector_env_refuses_bad_arguments_in_one_line(kwargs, message):
    with pytest.raises(ConfigError, match=message) as caught:
        AlignmentVectorEnv(scenario="ship-sway-rotary", **kwargs)
    assert "\n" not in str(caught.value)


def test_actions_of_the_wrong_shape_are_refused():
    env = AlignmentVectorEnv(2, scenario="ship-sway-rotary", **QUICK)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 4\)"):
        env.step(np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[0.0, np.nan, 0.0, 0.0]] * 2))
    env.close()


# --- the episode bank and the seed splits ----------------------------------------------
def test_bank_episode_is_the_fresh_simulation_bit_for_bit(tmp_path):
    experiment = experiment_for("ship-sway-rotary", fine_duration=12.0,
                                **QUICK["settings"])
    fresh = experiment.prepare_episode(41)
    stored = EpisodeBank(tmp_path, experiment).get(41)         # simulated, then stored
    loaded = EpisodeBank(tmp_path, experiment).get(41)         # loaded
    assert EpisodeBank(tmp_path, experiment).path(41).is_file()
    for name, value in fresh.arrays().items():
        assert_same(np.asarray(value), np.asarray(stored.arrays()[name]), name)
        assert_same(np.asarray(value), np.asarray(loaded.arrays()[name]), name)
    # Another setting, another bank directory: nothing mixes.
    other = experiment_for("ship-sway-rotary", fine_duration=13.0, **QUICK["settings"])
    assert EpisodeBank(tmp_path, other).directory != EpisodeBank(tmp_path, experiment).directory


def test_env_from_the_bank_rolls_out_as_from_a_simulation(tmp_path, capsys):
    def rollout(**kwargs):
        env = gym.make(SHIP_ID, cache_episodes=0, **QUICK, **kwargs)
        obs, _ = env.reset(seed=2, options={"episode_seed": 5})
        out = [obs]
        for _ in range(6):
            out.append(env.step(np.full(env.action_space.shape, 0.3, np.float32))[0])
        env.close()
        return np.array(out)

    fresh = rollout()
    assert np.array_equal(rollout(bank=tmp_path), fresh)       # simulated into the bank
    (path,) = tmp_path.glob("*/episodes/seed_5.npz")
    assert np.array_equal(rollout(bank=tmp_path), fresh)       # loaded from it
    path.write_bytes(b"damaged")
    assert np.array_equal(rollout(bank=tmp_path), fresh)       # named and simulated again
    assert "does not load" in capsys.readouterr().err


def test_seed_splits_are_disjoint_and_refused_when_crossed():
    ranges = sorted(SPLITS.values())
    assert ranges[0][0] == 0 and ranges[-1][1] == 2 ** 31 - 1
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))      # disjoint, no gap
    assert {split_of(s) for s in split_seeds("test", 3)} == {"test"}
    env = AlignmentVectorEnv(2, scenario="ship-sway-rotary", split="train", split_episodes=4,
                             **QUICK)
    _, info = env.reset(seed=0)
    assert all(0 <= s < 4 for s in info["episode_seed"])               # its first 4 seeds
    test_seed = split_seeds("test", 1)[0]
    with pytest.raises(ConfigError, match="'test' split"):
        env.reset(options={"episode_seed": test_seed})
    single = gym.make(SHIP_ID, split="validation", **QUICK)
    with pytest.raises(ConfigError, match="'train' split"):
        single.reset(options={"episode_seed": 3})
    with pytest.raises(ConfigError, match="first"):
        split_seeds("validation", SPLITS["validation"][1])


def test_bank_command_fills_the_bank_the_env_then_loads(tmp_path, capsys, monkeypatch):
    from aligngym.scenarios import cli
    argv = ["bank", "ship-sway-rotary", "--out", str(tmp_path), "--split", "validation",
            "--episodes", "2", "--episode-length", "12", "--workers", "1",
            "--set", "coarse_duration=20", "--set", "t_k1=8", "--set", "t_k2=20"]
    assert cli.main(argv) == 0
    assert "2 validation episodes" in capsys.readouterr().out
    files = sorted(tmp_path.glob("*/episodes/seed_*.npz"))
    assert [f.name for f in files] == [f"seed_{s}.npz" for s in split_seeds("validation", 2)]
    assert cli.main(argv) == 0 and "0 simulated" in capsys.readouterr().out

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated although the bank has the episode")
    env = gym.make(SHIP_ID, bank=tmp_path, split="validation", split_episodes=2,
                   cache_episodes=0, **QUICK)
    monkeypatch.setattr(env.unwrapped.experiment.__class__, "prepare_episode", no_simulation)
    for seed in range(4):
        _, info = env.reset(seed=seed)
        assert info["episode_seed"] in split_seeds("validation", 2)
    env.close()
    assert cli.main(["bank", "ship-sway-rotary", "--out", str(tmp_path), "--split",
                     "test", "--first", str(2 ** 31)]) == 2
    capsys.readouterr()
    assert cli.main([*argv, "--set", "fine_duration=20"]) == 2     # --episode-length's
    assert "set by episode_length" in capsys.readouterr().err


# Each model class and adaptation policy with state, beside the ship's imakf above:
# (env id, filter, settings: the shortest coarse stage each experiment accepts).
STAGGERED = [
    (SHIP_ID, "sakf", QUICK["settings"]),
    (SHIP_ID, "kf-sway", QUICK["settings"]),
    ("aligngym/Figure8Gps-v1", "rakf", {"coarse_duration": 5.0}),
    # R 1e-4 of its tuning: most fixes rejected, the rejection streaks run
    ("aligngym/Figure8Gps-v1", "rakf", {"coarse_duration": 5.0, "mistuning": 1e-4}),
    ("aligngym/Figure8Gps-v1", "swakf", {"coarse_duration": 5.0}),
    ("aligngym/RingRoadOdometer-v1", "sgkf", {"coarse_start": 5.0, "coarse_duration": 10.0}),
    ("aligngym/UsvMemsSwing-v1", "sage-husa", {"coarse_duration": 3.0}),
    ("aligngym/UsvMemsSwing-v1", "stukf", {"coarse_duration": 3.0}),
    ("aligngym/StaticLargeAzimuth-v1", "ukf", {}),
    ("aligngym/StaticLargeAzimuth-v1", "kf", {}),
    ("aligngym/StaticLargeAzimuth-v1", "sage-husa", {}),
]


@pytest.mark.parametrize("env_id, estimator, settings", STAGGERED)
def test_slots_at_different_epochs_equal_single_envs(env_id, estimator, settings):
    """Three slots in one batched filter, slots 0 and 1 reset alone at steps 1 and 2, 4-s
    episodes: the slots run at three different epochs and end at different steps (each
    waiting a step for its next-step reset while the others go on), and every output is
    that of three single envs, bit for bit, for each model class and stateful policy."""
    settings = dict(settings)
    mistuning = {"measurement": settings.pop("mistuning", 1.0)}
    kwargs = {"episode_length": 4.0, "estimator": estimator, "settings": settings,
              "mistuning": mistuning}
    game = {"steps": 12, "seed": 5, "resets": (1, 2), "slot": {1: 0, 2: 1}}
    native = gym.make_vec(env_id, num_envs=3, **kwargs)
    sync = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", **kwargs)
    a, b = play(native, **game), play(sync, **game)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            assert_same(u, v)
    ended = [np.flatnonzero(out[2] | out[3]).tolist() for out in a if len(out) == 5]
    assert len({tuple(e) for e in ended if e}) >= 3      # the slots end at different steps


def test_one_episode_seed_per_slot():
    env = AlignmentVectorEnv(3, scenario="ship-sway-rotary", **QUICK)
    _, info = env.reset(options={"episode_seed": [11, 12, 13]})
    assert info["episode_seed"].tolist() == [11, 12, 13] == env.episode_seeds.tolist()
    with pytest.raises(ConfigError, match="2 seeds for num_envs = 3"):
        env.reset(options={"episode_seed": [1, 2]})
    with pytest.raises(ConfigError, match="episode_seed must be an integer"):
        env.reset(options={"episode_seed": [1, -2, 3]})
    env.close()


def test_a_diverging_slot_ends_alone_and_is_charged_its_missing_epochs():
    """A filter made to diverge (measurement noise 1e-30, gyro noise 1e30 of its tuning):
    the diverged slots terminate, their last reward carries -100 per epoch not run, their
    metrics come once, and the vector env still equals the single envs bit for bit."""
    kwargs = {**QUICK, "estimator": "kf",
              "mistuning": {"measurement": 1e-30, "gyro_noise": 1e30}}
    native = gym.make_vec(SHIP_ID, num_envs=3, **kwargs)
    sync = gym.make_vec(SHIP_ID, num_envs=3, vectorization_mode="sync", **kwargs)
    a, b = play(native, 14, seed=3), play(sync, 14, seed=3)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            assert_same(u, v)
    ends = [(k, out) for k, out in enumerate(a[1:]) if out[2].any()]
    assert ends, "no slot diverged"
    k, (_, reward, terminated, _, info) = ends[0]
    i = int(np.flatnonzero(terminated)[0])
    assert reward[i] <= -100.0 * (12 - k - 1) and info["metrics"]["diverged"][i]
