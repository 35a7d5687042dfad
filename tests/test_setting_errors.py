"""Issue 46 item 6, issue 47 item 2: an experiment's settings are checked in one place
(``campaign.experiment.validate_settings``: type, finiteness, declared range) when the
experiment is made, before any work, and the one-line error names the setting as the user
wrote it: ``--set NAME``, ``--NAME``, the env's keyword, ``assert_alignment``'s keyword, a
scenario file's key with its unit suffix. The CLI answers with exit status 2 and writes
nothing to --out; the Python APIs raise ValueError."""
import contextlib
import io

import gymnasium as gym
import pytest

import aligngym  # noqa: F401  (registers the env ids)
import aligngym.scenarios.campaign.engine
import aligngym.scenarios.simulate
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import DATA_DIR, ConfigError, load_scenario
from aligngym.testing import assert_alignment

DURATION = "must be a finite number in (0, 86400] s"


class WorkStarted(Exception):
    """The check let the value through: an episode would be simulated."""


def _no_work(*args, **kwargs):
    raise WorkStarted


@pytest.fixture(autouse=True)
def no_work(monkeypatch):
    monkeypatch.setattr(aligngym.scenarios.campaign.engine, "prepare_all", _no_work)
    monkeypatch.setattr(aligngym.scenarios.simulate, "simulate", _no_work)


def cli(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue()


@pytest.mark.parametrize("argv, message", [
    (["bench", "paper003", "--set", "fine_duration=-5"], f"--set fine_duration {DURATION}, got -5"),
    (["bench", "paper002", "--set", "filter_step=0"],
     "--set filter_step must be a finite number > 0 s, got 0"),
    (["bench", "paper003", "--set", "fine_duration=true"], f"--set fine_duration {DURATION}, got True"),
    (["bench", "paper003", "--set", "fine_duration=inf"], f"--set fine_duration {DURATION}, got inf"),
    (["bench", "paper003", "--set", "fine_duration=abc"],
     f"--set fine_duration {DURATION}, got 'abc'"),
    (["bench", "paper002", "--set", "fine_duration=0.5"],          # the default step is 1 s
     "--set fine_duration must be >= filter_step (1 s), got 0.5"),
    (["bench", "paper003", "--set", "filter_step=0.003"], "--set filter_step must be a whole "
     "number (>= 1) of the scenario's IMU intervals of 0.01 s, got 0.003"),
    (["bench", "paper001", "--outage", "-1"], "--outage must be a finite number in [0, 86400] s, "
     "got -1"),
    (["bench", "paper001", "--outage", "nan"], "--outage must be a finite number in [0, 86400] s, "
     "got nan"),
    (["bank", "ship-sway-rotary", "--set", "coarse_duration=-5"],
     "--set coarse_duration must be a finite number in (0, 86400] s, got -5"),
    (["bank", "ship-sway-rotary", "--episode-length", "1e6"], f"--episode-length {DURATION}, "
     "got 1000000.0"),
])
def test_a_bad_setting_is_one_line_naming_it_as_written(argv, message, tmp_path):
    out = tmp_path / "out"
    code, err = cli([*argv, "--out", str(out)] + (["--episodes", "1"] if argv[0] == "bench"
                                                    else []))
    assert code == 2 and err == f"aligngym: error: {message}\n"
    assert not out.exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"episode_length": -5.0}, f"episode_length {DURATION}, got -5.0"),
    ({"episode_length": True}, f"episode_length {DURATION}, got True"),
    ({"epoch_length": 0}, "epoch_length must be a finite number > 0 s, got 0"),
    ({"settings": {"coarse_duration": float("inf")}},
     f"settings['coarse_duration'] {DURATION}, got inf"),
    ({"settings": {"rho": 2}}, "settings['rho'] must be a finite number in (0, 1], got 2"),
])
def test_the_env_names_its_keyword(kwargs, message):
    with pytest.raises(ValueError) as error:
        gym.make("aligngym/ShipSwayRotary-v1", **kwargs)
    assert str(error.value) == message


@pytest.mark.parametrize("kwargs, message", [
    ({"fine_duration": -5}, f"assert_alignment: fine_duration {DURATION}, got -5"),
    ({"fine_duration": "600"}, f"assert_alignment: fine_duration {DURATION}, got '600'"),
    ({"filter_step": 0.0}, "assert_alignment: filter_step must be a finite number > 0 s, "
     "got 0.0"),
])
def test_assert_alignment_names_its_keyword(kwargs, message):
    with pytest.raises(ValueError) as error:
        assert_alignment("kf", "ship-sway-rotary", episodes=1, **kwargs)
    assert str(error.value) == message


def test_a_scenario_file_key_is_named_with_its_unit_suffix(tmp_path):
    text = (DATA_DIR / "ship-sway-rotary.toml").read_text()
    assert "duration_s = 600.0" in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("duration_s = 600.0", "duration_s = -5"))
    with pytest.raises(ConfigError, match=r"^run\.duration_s = -5 s is out of range "
                                          r"\(0, 86400\]$"):
        load_scenario(str(bad))
    code, err = cli(["simulate", "ship-sway-rotary", "--duration", "1e5", "--out",
                     str(tmp_path / "x.npz")])
    assert code == 2 and err == ("aligngym: error: --duration = 100000 s is out of range "
                                 "(0, 86400]\n")


def test_the_python_api_names_the_field():
    from aligngym.scenarios.experiments.paper003 import Paper003Experiment
    with pytest.raises(ConfigError, match=r"^attitude_sigma_deg must be a list of 3 finite "
                                          r"numbers > 0 deg, got \(1.0, -1.0, 5.0\)$"):
        Paper003Experiment(attitude_sigma_deg=(1.0, -1.0, 5.0))
    exp = Paper003Experiment(attitude_sigma_deg=[1, 1, 5], fine_duration=300)
    assert exp.attitude_sigma_deg == (1, 1, 5) and exp.fine_duration == 300
