"""The DVL used by an experiment that is not a paper's (tests/dvl_experiment.py: DVL-aided
fine alignment on the swaying ship, the DVL's bias a state): against physics with
error-free sensors from a start beyond the coarse stage's, its heading errors against its
own sigma on erroneous sensors, and run through bench, the env and assert_alignment."""
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.models.units import arcmin, deg
from aligngym.scenarios import registry
from aligngym.scenarios.campaign import episode_seeds
from aligngym.scenarios.campaign.runs import run_filter_starts
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import register_experiment
from aligngym.sensors.imu import ImuSpec
from aligngym.testing import assert_alignment
from dvl_experiment import DVL_BIAS, DvlAidedExperiment

SHIP = Path(__file__).resolve().parents[1] / "scenarios" / "data" / "ship-sway-rotary.toml"
DVL = """
[dvl]
rate_hz = 2.0
velocity_sigma = {noise}
bias_sigma = {bias}
scale_factor_sigma = {scale}
lever_arm_b_m = [-10.0, -30.0, -12.0]    # at the keel, 2 m below the sway centre
"""


def scenario(folder: Path, name: str, noise: float, bias: float, scale: float) -> str:
    """Paper 003's ship with a DVL ([dvl]), run by the DVL-aided experiment."""
    text = (SHIP.read_text().replace('name = "ship-sway-rotary"', f'name = "{name}"')
            .replace('experiment = "paper003"', 'experiment = "dvl-aided"')
            + DVL.format(noise=noise, bias=bias, scale=scale))
    path = folder / f"{name}.toml"
    path.write_text(text)
    return str(path)


@pytest.fixture(scope="module")
def ship(tmp_path_factory):
    register_experiment("dvl-aided", DvlAidedExperiment)
    folder = tmp_path_factory.mktemp("dvl")
    yield {"real": scenario(folder, "ship-dvl", 0.01, 0.005, 0.002),
           "ideal": scenario(folder, "ship-dvl-ideal", 0.0, 0.0, 0.0),
           "biased": scenario(folder, "ship-dvl-biased", 0.0, 0.05, 0.0)}
    registry._REGISTERED.pop("dvl-aided", None)


@pytest.mark.parametrize("dvl", ["ideal", "biased"])
def test_error_free_sensors_align_to_the_floor_from_beyond_the_coarse_start(ship, dvl):
    """An error-free IMU and a DVL without noise, exact ("ideal") or with a bias of 5 cm/s
    per axis and episode, which the filter must estimate through the sway ("biased"); the
    hull swaying (10 deg roll, 0.3 m heave): from the largest coarse error and from (0.5,
    -0.5, 3) deg, the final level error is within 0.02' and the heading within 0.5' (the R
    floor's sigma, 0.46'), each within 3 sigma, and the DVL bias's estimate within
    3 sigma + 1 mm/s of the bias drawn; the innovations are far below the R floor
    (mean NIS over the second half < 1, against 3 for noise at the floor: an error of
    1 % of the sway velocity in the measurement is well above it)."""
    exp = DvlAidedExperiment(scenario=ship[dvl], fine_duration=300.0)
    error_free = replace(exp.scenario_config(), imu=ImuSpec())
    episodes = [exp.prepare_episode(s, config=error_free) for s in episode_seeds(0, 2)]
    starts = {"max": exp.start_errors(episodes)["max"],
              "wide": np.array([0.5, -0.5, 3.0]) * deg}
    for run in run_filter_starts("kf", starts, episodes, exp):
        error, sigma = run.error_n[:, -1], run.result.sigma_n[:, -1]
        assert np.all(np.abs(error[:, :2]) < 0.02 * arcmin), (run.start, error / arcmin)
        assert np.all(np.abs(error[:, 2]) < 0.5 * arcmin), (run.start, error / arcmin)
        assert np.all(np.abs(error) < 3.0 * sigma), (run.start, error / sigma)
        nis = run.result.nis[:, run.result.nis.shape[1] // 2:]
        assert np.nanmean(nis) < 1.0, (run.start, np.nanmean(nis))
        bias = np.stack([e.dvl_bias for e in episodes])
        bias_error = run.result.x[:, -1, DVL_BIAS] - bias
        bias_sigma = np.sqrt(np.diagonal(run.result.P[:, -1, DVL_BIAS, DVL_BIAS], 0, -2, -1))
        assert np.all(np.abs(bias_error) < 3.0 * bias_sigma + 1e-3), (bias, bias_error)


def test_heading_errors_match_the_filters_sigma_on_erroneous_sensors(ship):
    """Datasheet IMU errors and the DVL's noise, bias and scale factor: the sum of the
    squared heading errors over their sigmas at the end lies in the 99.9 % chi-square(4)
    band [0.091, 18.5] (R off by 10x, or the DVL bias left out, is far above)."""
    exp = DvlAidedExperiment(scenario=ship["real"], fine_duration=300.0)
    episodes = [exp.prepare_episode(s) for s in episode_seeds(0, 4)]
    (run,) = run_filter_starts("kf", {"mean": exp.start_errors(episodes)["mean"]},
                               episodes, exp)
    z = run.error_n[:, -1, 2] / run.result.sigma_n[:, -1, 2]
    assert 0.091 < np.sum(z ** 2) < 18.5, z
    assert np.all(run.status == "converged")


def test_it_runs_in_bench_the_env_and_assert_alignment(ship, capsys):
    assert main(["bench", "dvl-aided", "--scenario", ship["real"], "--episodes", "2",
                 "--fine-duration", "120", "--workers", "1", "--no-figures"]) == 0
    assert "2 episodes x 2 filters x 2 start(s)" in capsys.readouterr().out
    env = gym.make("aligngym/Alignment-v1", scenario=ship["real"], estimator="kf",
                   episode_length=10.0)
    obs, _ = env.reset(seed=1)
    obs, *_ = env.step(np.zeros(env.action_space.shape))
    assert np.all(np.isfinite(obs))
    env.close()
    measured = assert_alignment("kf", ship["real"], episodes=2, heading_rms_arcmin=10.0,
                                level_rms_arcmin=1.0)
    assert measured["diverged"] == 0


def test_a_scenario_without_a_dvl_is_refused_in_one_line(ship):
    exp = DvlAidedExperiment()
    with pytest.raises(ConfigError, match=r"needs a \[dvl\] table; scenario "
                                          "'ship-sway-rotary' has none"):
        exp.check(exp.scenario_config())
