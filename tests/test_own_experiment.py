"""A new experiment is one file: declared once (a frozen Experiment subclass with its
settings, default episode count and regression campaign) and registered, it runs in
``bench`` (a declared setting as its own option, any other through --set), ``regress``, behind a scenario file's
``experiment`` key and the generic env id, with no edit anywhere else."""
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.scenarios import registry
from aligngym.scenarios.campaign import setting
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment, register_experiment
from aligngym.scenarios.experiments.paper002 import Paper002Experiment
from aligngym.scenarios.regress import campaigns, regress


@dataclass(frozen=True)
class QuickTableExperiment(Paper002Experiment):
    """Paper 002's static base from a 20 deg azimuth error, 60 s, the EKF alone."""

    fine_duration: float = 60.0
    azimuth_error_deg: float = setting(20.0, "the start's azimuth error", unit="deg",
                                       minimum=0.0)
    default_filters: tuple[str, ...] = ("ekf",)

    default_episodes = 3
    regress = {"episodes": 2, "seed": 4, "filters": ["ekf"]}


SCENARIO = """name = "quick-table"
experiment = "quick-table"
world = "static-platform"
[origin]
latitude_deg = 30.0
longitude_deg = 10.0
height_m = 0.0
[run]
duration_s = 60.0
imu_rate_hz = 100.0
[imu]
preset = "paper002-static"
[motion]
yaw_deg = 10.0
pitch_deg = 0.0
roll_deg = 0.0
"""


@pytest.fixture
def registered(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    register_experiment("quick-table", QuickTableExperiment)
    path = tmp_path / "quick-table.toml"
    path.write_text(SCENARIO)
    yield str(path)
    registry._REGISTERED.pop("quick-table", None)


def test_a_registered_experiment_runs_everywhere(registered, tmp_path, capsys):
    assert "quick-table" in registry.experiment_names()
    assert main(["bench", "quick-table", "--scenario", registered, "--azimuth-error-deg",
                 "10", "--json", "q.json", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "3 runs" in out and "10 deg azimuth error" in out     # its default episodes
    assert campaigns()["quick-table"] == QuickTableExperiment.regress
    exp = experiment("quick-table", scenario=registered)
    assert regress(["quick-table"], update=True, directory=tmp_path)[0]
    passed, report = regress(["quick-table"], directory=tmp_path)
    assert passed and "quick-table: " in report
    env = gym.make("aligngym/Alignment-v1", scenario=registered, estimator="ekf",
                   episode_length=10.0)
    env.reset(seed=1)
    assert isinstance(env.unwrapped.experiment, QuickTableExperiment)
    obs, *_ = env.step(np.zeros(env.action_space.shape))
    assert np.all(np.isfinite(obs))
    env.close()
    assert exp.fine_duration == 60.0


def test_bad_settings_and_registrations_are_one_line_errors(registered, capsys):
    assert main(["bench", "quick-table", "--set", "no_such=1"]) == 2
    assert "--set 'no_such=1': need NAME=VALUE with NAME a setting of quick-table" in \
        capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:            # paper004's option, not this one's
        main(["bench", "quick-table", "--swing", "mild"])
    assert stop.value.code == 2
    assert ("unrecognized arguments: --swing mild ('aligngym bench quick-table --help' lists "
            "its settings" in capsys.readouterr().err)
    assert main(["bench", "quick-table", "--azimuth-error-deg", "-5"]) == 2
    assert ("aligngym: error: --azimuth-error-deg must be a finite number >= 0 deg, got -5\n"
            == capsys.readouterr().err)


def test_a_declared_setting_is_an_option_with_its_doc(registered, capsys):
    with pytest.raises(SystemExit):
        main(["bench", "quick-table", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "settings of QuickTableExperiment: --azimuth-error-deg DEG the start's azimuth " \
        "error, deg; default: 20.0" in out
    assert "fine_duration (60.0)" in out                # the others, for --set
    with pytest.raises(ConfigError, match="is not an Experiment subclass"):
        register_experiment("x", dict)
    with pytest.raises(ConfigError, match="'paper002' is taken"):
        register_experiment("paper002", QuickTableExperiment)
