"""A user's own scenario file, outside the package, is a full citizen: the experiment its
``experiment`` key names runs on it in ``bench``, behind the generic env id, in
``evaluate``, ``assert_alignment`` and ``render --estimator``."""
import gymnasium as gym
import numpy as np
import pytest

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.scenarios import evaluate
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.experiments import experiment_for
from aligngym.scenarios.registry import GENERIC_ENV_ID
from aligngym.testing import assert_alignment

OWN = """name = "my-bench-table"
experiment = "paper002"
world = "static-platform"
[origin]
latitude_deg = 52.0
longitude_deg = 5.0
height_m = 30.0
[run]
duration_s = 120.0
imu_rate_hz = 100.0
[imu]
preset = "paper002-static"
[motion]
yaw_deg = -70.0
pitch_deg = 1.0
roll_deg = 0.5
"""
"""A marble table elsewhere (52 N, heading 70 deg west of north, 1 deg of pitch)."""


@pytest.fixture
def own(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "my-table.toml"
    path.write_text(OWN)
    return str(path)


def test_the_experiment_key_is_the_map(own, tmp_path):
    exp = experiment_for(own, fine_duration=60.0)
    assert exp.paper == "002" and exp.scenario == own
    assert load_scenario(own).experiment == "paper002"
    none = tmp_path / "none.toml"
    none.write_text(OWN.replace('experiment = "paper002"\n', ""))
    with pytest.raises(ConfigError, match="names no experiment"):
        experiment_for(str(none))
    bad = tmp_path / "bad.toml"
    bad.write_text(OWN.replace('"paper002"', '"paper999"'))
    with pytest.raises(ConfigError, match="experiment = 'paper999' is unknown"):
        load_scenario(str(bad))


def test_bench_env_evaluate_assert_and_render_run_on_it(own, tmp_path):
    assert main(["bench", "paper002", "--scenario", own, "--episodes", "2", "--filters",
                 "ekf", "--workers", "1", "--json", "s.json"]) == 0
    env = gym.make(GENERIC_ENV_ID, scenario=own, estimator="ekf", episode_length=60.0)
    obs, _ = env.reset(seed=3)
    assert env.unwrapped.experiment.scenario == own
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert np.all(np.isfinite(obs)) and np.isfinite(reward) and not terminated
    env.close()
    rows = evaluate(GENERIC_ENV_ID, "ekf", episodes=1, seed=3, scenario=own,
                    episode_length=60.0)
    assert len(rows) == 1 and rows[0]["filter"] == "ekf"
    measured = assert_alignment("ekf", own, episodes=1, seed=3, level_rms_arcmin=1.0,
                                fine_duration=60.0)
    assert measured["diverged"] == 0
    out = tmp_path / "frame.png"
    assert main(["render", own, "--start", "10", "--estimator", "ekf", "--size", "96x128",
                 "--out", str(out)]) == 0
    assert out.stat().st_size > 0
