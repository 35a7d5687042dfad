"""Every file in scenarios/data/ is an env (issue 46 item 5): its own id
``aligngym/<Scenario>-v1``, the generic id with its name or its path, and ``evaluate`` run
it with its experiment's setup: the default one for a file that names its experiment, the
paper one (``bench EXPERIMENT --setup paper``) for a ``*-paper`` file. What each file
should run is read here from the file alone (its ``experiment`` key, else its name and
``paper`` key), not from ``experiments.setup_for``."""
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

from aligngym import scenarios
from aligngym.envs import ENV_IDS, ENV_SCENARIOS
from aligngym.scenarios.campaign import episode_seeds
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.env_core import OBS_SIZE
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.registry import DATA_DIR, GENERIC_ENV_ID, env_id, scenario_names

SHIPPED = scenario_names()
LENGTH = 3.0                       # s of fine alignment: 3 epochs
QUICK = {"paper000": {"coarse_duration": 10.0}, "paper001": {"coarse_duration": 5.0},
         "paper002": {}, "paper003": {"coarse_duration": 10.0, "t_k1": 4.0, "t_k2": 10.0},
         "paper004": {"coarse_duration": 5.0}}
"""A short coarse stage (the env's contract is under test, not the alignment; paper 000
takes no less than 10 s)."""
SEED = episode_seeds(0, 1)[0]      # evaluate's first episode: simulated once, shared


def expected(name: str) -> tuple[str, str]:
    """(experiment, setup) the file's own words ask for."""
    config = load_scenario(name)
    if config.experiment:
        return config.experiment, "default"
    assert name.endswith("-paper") and config.paper, \
        f"{name} names no experiment and is no *-paper file of a paper"
    return f"paper{config.paper}", "paper"


def make(id_: str, name: str, **kwargs):
    return gym.make(id_, estimator="kf", episode_length=LENGTH,
                    settings=QUICK[expected(name)[0]], **kwargs)


def test_every_shipped_file_has_its_id():
    assert ENV_SCENARIOS == SHIPPED and len(ENV_IDS) == len(SHIPPED)
    assert {"figure8-gps-paper", "ship-sway-rotary-paper"} <= set(SHIPPED)
    for name in SHIPPED:
        spec = gym.spec(env_id(name))
        assert spec.kwargs == {"scenario": name}
        assert spec.vector_entry_point.endswith("AlignmentVectorEnv")
    assert gym.spec("aligngym/ShipSwayRotaryPaper-v1").kwargs["scenario"] \
        == "ship-sway-rotary-paper"


@pytest.mark.parametrize("name", SHIPPED)
def test_env_runs_every_file_with_its_setup(name):
    """The generic id by name: the file's experiment in its setup, on the file itself;
    one reset and one step. Its own id and its path make the same experiment."""
    exp_name, setup = expected(name)
    env = make(GENERIC_ENV_ID, name, scenario=name)
    exp = env.unwrapped.experiment
    assert exp == experiment(exp_name, setup=setup, scenario=name, fine_duration=LENGTH,
                             filter_step=1.0, **QUICK[exp_name])
    assert getattr(exp, "setup", "default") == setup
    assert env.unwrapped.config.name == name
    obs, info = env.reset(seed=0, options={"episode_seed": SEED})
    assert obs.shape == (OBS_SIZE,) and info["episode_seed"] == SEED
    obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape,
                                                                 np.float32))
    assert env.observation_space.contains(obs) and np.isfinite(reward)
    assert not terminated and not truncated and info["time_s"] == 1.0
    env.close()
    assert make(env_id(name), name).unwrapped.experiment == exp
    by_path = make(GENERIC_ENV_ID, name, scenario=str(DATA_DIR / f"{name}.toml"))
    assert replace(by_path.unwrapped.experiment, scenario=name) == exp


@pytest.mark.parametrize("name", SHIPPED)
def test_evaluate_runs_every_file(name):
    """One episode of LENGTH s through the file's own id."""
    rows = scenarios.evaluate(env_id(name), "kf", episodes=1, episode_length=LENGTH,
                              settings=QUICK[expected(name)[0]])
    assert [r["seed"] for r in rows] == [SEED]
    assert np.isfinite(rows[0]["final_phi_U_arcmin"]) and rows[0]["status"] != "diverged"


def test_paper_setup_reaches_the_filter():
    """ship-sway-rotary-paper's setup sets the calm-sea R (3 mm/s) that the default setup
    derives from the sway instead: the env's filter model holds the paper's, its twin's
    the derived one; evaluate by the generic id gives the paper id's numbers."""
    sigmas = {}
    for name in ("ship-sway-rotary", "ship-sway-rotary-paper"):
        env = make(env_id(name), name)
        env.reset(seed=0, options={"episode_seed": SEED})
        sigmas[name] = env.unwrapped._run.model.tuning.measurement_sigma
        env.close()
    paper = experiment("paper003", setup="paper").measurement_sigma
    assert paper is not None and tuple(sigmas["ship-sway-rotary-paper"]) == tuple(paper)
    assert not np.allclose(sigmas["ship-sway-rotary"], paper)
    kwargs = {"episodes": 1, "episode_length": LENGTH, "settings": QUICK["paper003"]}
    assert scenarios.evaluate(GENERIC_ENV_ID, "kf", scenario="ship-sway-rotary-paper",
                              **kwargs)[0]["final_phi_U_arcmin"] \
        == scenarios.evaluate("aligngym/ShipSwayRotaryPaper-v1", "kf",
                              **kwargs)[0]["final_phi_U_arcmin"]


def test_setup_and_scenario_errors_are_one_line():
    """A *-paper file's settings may repeat its setup, not name another; a scenario that
    is no name or path is refused naming the field and the shipped names."""
    name = "ship-sway-rotary-paper"
    same = make(GENERIC_ENV_ID, name, scenario=name).unwrapped.experiment
    again = gym.make(GENERIC_ENV_ID, scenario=name, episode_length=LENGTH,
                     settings={**QUICK["paper003"], "setup": "paper"})
    assert again.unwrapped.experiment == same
    with pytest.raises(ConfigError, match=r"^settings setup = 'default': "
                       r"ship-sway-rotary-paper is paper003's 'paper' setup; "
                       r"valid: 'paper'$"):
        gym.make(GENERIC_ENV_ID, scenario=name, settings={"setup": "default"})
    for bad in (42, "", None):
        with pytest.raises(ConfigError, match=r"^scenario = .*; valid: a shipped name "
                           r"\(figure8-gps, .*ship-sway-rotary-paper.*\) or a \.toml path$"):
            gym.make(GENERIC_ENV_ID, scenario=bad)
    with pytest.raises(ConfigError, match="unknown scenario 'nope'; valid choices: .*-paper"):
        gym.make(GENERIC_ENV_ID, scenario="nope")
