"""Interrupted, full, corrupted and concurrent runs lose nothing and end in one line:
atomic outputs, damaged campaign directories on --resume, Ctrl-C and OSError in the CLI,
the campaign lock, --resume with other filters, the env's and the API's argument checks,
a lost filter reported as diverged, and runs refused before they start (memory,
degenerate scenarios, malformed baselines)."""
import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import aligngym
from aligngym.estimators.metrics import StatusRule
from aligngym.models.units import arcmin
from aligngym.scenarios import simulate as simulate_module
from aligngym.scenarios.atomic import atomic_path, is_temporary, write_json
from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.campaign.manifest import campaign_lock
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.regress import flatten, regress

QUICK = {"fine_duration": 30.0}
"""Paper 002's static base for 30 s: an episode costs a few ms."""


def quick(**settings):
    return experiment("paper002", **{**QUICK, **settings})


def bench_argv(out, *extra, episodes=3):
    return ["bench", "paper002", "--episodes", str(episodes), "--filters", "ekf",
            "--set", "fine_duration=30", "--workers", "1", "--no-figures", "--out", str(out),
            *extra]


def cli(*args):
    return [sys.executable, "-m", "aligngym.scenarios.cli", *args]


def last_line(text: str) -> str:
    return text.strip().splitlines()[-1]


# --- 1. atomic outputs --------------------------------------------------------------------
def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "x.json"
    write_json(target, {"old": True})
    with pytest.raises(OSError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert json.loads(target.read_text()) == {"old": True}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.json"]


def test_simulate_on_a_full_disk_is_one_line_and_keeps_the_old_file(tmp_path, monkeypatch,
                                                                   capsys):
    out = tmp_path / "e.npz"
    assert main(["simulate", "static-large-azimuth", "--duration", "2", "--out", str(out)]) == 0
    before = out.read_bytes()

    def full(path, **arrays):
        Path(path).write_bytes(b"PK\x03\x04 half an archive")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(np, "savez", full)
    capsys.readouterr()
    assert main(["simulate", "static-large-azimuth", "--duration", "2", "--seed", "1",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "No space left on device" in err
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["e.npz"]


# --- 2. damaged campaign directories ------------------------------------------------------
DAMAGE = {
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "empty": lambda p: p.write_bytes(b""),
    "flipped": lambda p: p.write_bytes(p.read_bytes()[:200] + bytes(
        b ^ 0xFF for b in p.read_bytes()[200:400]) + p.read_bytes()[400:]),
    "text": lambda p: p.write_text("not an episode"),
}


@pytest.fixture(scope="module")
def clean_campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("clean")
    result = run_campaign(quick(), episodes=4, seed=7, filters=["ekf"], out_dir=out,
                          workers=1, progress=False)
    return out, flatten(result.summary())


def copy_campaign(source: Path, target: Path) -> Path:
    import shutil
    shutil.copytree(source, target)
    return target


def counting_prepare(monkeypatch):
    from aligngym.scenarios.experiments.paper002 import Paper002Experiment
    calls = []
    original = Paper002Experiment.prepare_episode

    def prepare(self, seed, config=None):
        calls.append(seed)
        return original(self, seed, config)

    monkeypatch.setattr(Paper002Experiment, "prepare_episode", prepare)
    return calls


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_resume_names_a_damaged_episode_and_simulates_it_again(damage, clean_campaign,
                                                               tmp_path, monkeypatch, capsys):
    source, expected = clean_campaign
    out = copy_campaign(source, tmp_path / "c")
    bad = out / "episodes" / "seed_7000002.npz"
    DAMAGE[damage](bad)
    calls = counting_prepare(monkeypatch)
    result = run_campaign(quick(), episodes=4, seed=7, filters=["ekf"], out_dir=out,
                          workers=1, progress=False, resume=True)
    assert calls == [7000002]                       # only the damaged one, not the good
    assert f"{bad} does not load" in capsys.readouterr().err
    assert flatten(result.summary()) == expected
    np.load(bad).close()                             # rewritten whole


def test_an_episode_of_another_seed_is_not_taken(clean_campaign, tmp_path, monkeypatch,
                                                 capsys):
    out = copy_campaign(clean_campaign[0], tmp_path / "c")
    episodes = out / "episodes"
    (episodes / "seed_7000001.npz").write_bytes((episodes / "seed_7000003.npz").read_bytes())
    calls = counting_prepare(monkeypatch)
    run_campaign(quick(), episodes=4, seed=7, filters=["ekf"], out_dir=out, workers=1,
                 progress=False, resume=True)
    assert calls == [7000001] and "holds seed 7000003" in capsys.readouterr().err


@pytest.mark.parametrize("text, why", [("{not json", "does not read as JSON"),
                                       ("[1, 2]", "holds a JSON list, not an object"),
                                       ("", "does not read as JSON")])
def test_a_damaged_manifest_is_one_line_saying_what_to_do(text, why, clean_campaign,
                                                          tmp_path, capsys):
    out = copy_campaign(clean_campaign[0], tmp_path / "c")
    (out / "campaign.json").write_text(text)
    assert main(bench_argv(out, "--resume", episodes=4)) == 2
    line = last_line(capsys.readouterr().err)
    assert why in line and "use --force" in line and line.startswith("aligngym: error:")


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning",
                            "error::pytest.PytestUnhandledThreadExceptionWarning")
@settings(max_examples=12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cuts=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 30000), st.booleans()),
                     min_size=1, max_size=3))
def test_fuzzed_damage_before_resume_completes_or_is_one_line(cuts, clean_campaign,
                                                              tmp_path_factory):
    """Random truncation or corruption of episode files (index 0-3) and of the manifest
    (index 4): --resume completes with the clean run's numbers, recomputing only the
    damaged episodes, or ends in one error line; never a traceback."""
    source, expected = clean_campaign
    out = copy_campaign(source, tmp_path_factory.mktemp("fuzz") / "c")
    files = sorted((out / "episodes").glob("seed_*.npz")) + [out / "campaign.json"]
    good = {p: p.read_bytes() for p in files[:4]}
    for index, at, flip in cuts:
        data = files[index].read_bytes()
        at = min(at, len(data))
        files[index].write_bytes(data[:at] + (bytes(b ^ 0x5A for b in data[at:at + 64])
                                              + data[at + 64:] if flip else b""))
    # In this process: an uncaught exception, or one Python could only print (a
    # finaliser's: an unraisable-exception warning, made an error), fails the test.
    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        code = main(bench_argv(out, "--resume", "--json", str(out / "s.json"), episodes=4))
    assert "Traceback" not in err.getvalue()
    if code:
        assert code == 2 and last_line(err.getvalue()).startswith("aligngym: error:")
        return
    assert flatten(json.loads((out / "s.json").read_text())) == expected
    damaged = {p for p, data in good.items() if p.read_bytes() != data}
    assert not damaged, "a damaged episode file was not rewritten whole"


# --- 3. Ctrl-C and OSError in the CLI -----------------------------------------------------
STACKS_ON_SIGUSR1 = ("import faulthandler, signal, sys; "
                     "faulthandler.register(signal.SIGUSR1, all_threads=True); "
                     "from aligngym.scenarios.cli import main; sys.exit(main(sys.argv[1:]))")
"""The command line run with every thread's stack written to stderr on SIGUSR1 (in the
campaign's forked workers too): a run that hangs is shown where, not only timed out."""


def communicate_or_show_stacks(proc: subprocess.Popen, timeout: float) -> str:
    """proc's stderr once it ends; if it has not ended after timeout s, its process group's
    stacks (``STACKS_ON_SIGUSR1``) in the failure, and the group killed."""
    try:
        return proc.communicate(timeout=timeout)[1]
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGUSR1)
        time.sleep(2.0)
        os.killpg(proc.pid, signal.SIGKILL)
        err = proc.communicate()[1]
        pytest.fail(f"the command did not end within {timeout:g} s; its stacks:\n{err}")


def test_ctrl_c_mid_campaign_is_one_line_exit_130_and_resume_continues(tmp_path):
    out = tmp_path / "c"
    argv = ["bench", "paper002", "--episodes", "40", "--filters", "ekf", "--workers", "2",
            "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-c", STACKS_ON_SIGUSR1, *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 60
    while len(list((out / "episodes").glob("seed_*.npz"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGINT)                 # as a terminal's Ctrl-C
    err = communicate_or_show_stacks(proc, 60)
    assert proc.returncode == 130 and "Traceback" not in err
    line = last_line(err)
    kept = len(list((out / "episodes").glob("seed_*.npz")))
    assert line.startswith(f"aligngym: interrupted; {kept} finished episode(s) kept in {out}")
    assert line.endswith(f"--out {out} --resume")
    assert not [p for p in (out / "episodes").iterdir() if is_temporary(p)]
    for path in (out / "episodes").glob("seed_*.npz"):     # every kept file is whole
        np.load(path).close()


def test_an_oserror_while_writing_results_is_one_line(tmp_path, monkeypatch, capsys):
    import aligngym.scenarios.report as report

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "c" / "x"))

    monkeypatch.setattr(report, "write_json", full)
    assert main(bench_argv(tmp_path / "c")) == 2
    err = capsys.readouterr().err
    assert last_line(err) == f"aligngym: error: {tmp_path / 'c' / 'x'}: No space left on device"


# --- 4. one writer per campaign directory -------------------------------------------------
def test_a_second_writer_is_refused_naming_the_holder(tmp_path):
    out = tmp_path / "c"
    out.mkdir()
    with campaign_lock(out):
        run = subprocess.run(cli(*bench_argv(out)), capture_output=True, text=True)
    assert run.returncode == 2
    assert f"is in use by pid {os.getpid()} on " in last_line(run.stderr)
    assert main(bench_argv(out)) == 0                     # released: the lock is free again


# --- 5. --resume with other filters -------------------------------------------------------
def test_resume_never_drops_finished_filters(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(bench_argv(out)) == 0
    argv = [a if a != "ekf" else "ukf" for a in bench_argv(out, "--resume")]
    assert main(argv) == 2
    assert "would drop ekf: name them too (--filters ekf,ukf)" in capsys.readouterr().err
    argv = [a if a != "ekf" else "ukf,ekf" for a in bench_argv(out, "--resume")]
    assert main(argv) == 0
    rows = (out / "results.csv").read_text()
    assert rows.count(",ekf,") == 3 and rows.count(",ukf,") == 3


# --- 6. the env's and the API's arguments -------------------------------------------------
@pytest.fixture(scope="module")
def static_env():
    env = gym.make("aligngym/StaticLargeAzimuth-v1", estimator="ekf", episode_length=5.0)
    env.reset(seed=1)
    yield env
    env.close()


@pytest.mark.parametrize("options, message", [
    ({"start_eror": "random"}, "reset option 'start_eror' is unknown; valid: episode_seed, "
                               "start_error"),
    ([("start_error", "random")], "reset options must be a dict, got list"),
    ({"episode_seed": -3}, "episode_seed must be an integer >= 0, got -3"),
    ({"episode_seed": 2.5}, "episode_seed must be an integer >= 0, got 2.5"),
    ({"start_error": [1j, 0, 0]}, "start_error must be 3 finite angles in rad (E, N, U), got "
                                  "complex128 values")])
def test_reset_refuses_what_it_cannot_use(static_env, options, message):
    with pytest.raises(ConfigError) as err:
        static_env.reset(seed=1, options=options)
    assert str(err.value) == message


@pytest.mark.parametrize("action", [np.array([0.1 + 0.5j, 0, 0]), np.array(["a", "b", "c"]),
                                    np.array([True, False, True]), [None, 0, 0]])
def test_step_refuses_complex_text_boolean_and_object_actions(static_env, action):
    static_env.reset(seed=1)
    with pytest.raises(ValueError, match="action must be 3 real numbers in"):
        static_env.step(action)


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(action=st.one_of(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
                        st.lists(st.integers(-10 ** 20, 10 ** 20), max_size=4),
                        st.lists(st.complex_numbers(), min_size=3, max_size=3),
                        st.text(max_size=3), st.none()),
       options=st.one_of(st.none(), st.dictionaries(
           st.sampled_from(["episode_seed", "start_error", "seed", "x"]),
           st.one_of(st.integers(-5, 5), st.floats(), st.text(max_size=4),
                     st.lists(st.floats(), max_size=4)), max_size=2)))
def test_fuzzed_reset_and_step_accept_or_refuse_in_one_line(static_env, action, options):
    try:
        static_env.reset(seed=1, options=options)
    except ConfigError as exc:
        assert "\n" not in str(exc)
        return
    try:
        _, reward, *_ = static_env.step(action)
    except ValueError as exc:
        assert "\n" not in str(exc) and "action" in str(exc)
        return
    assert np.isfinite(reward)


def test_register_filter_checks_its_factories_at_once():
    with pytest.raises(TypeError, match="returned dict, not an IntegrationRule"):
        aligngym.register_filter("bad-rule", dict)
    with pytest.raises(TypeError, match="returned int, not an AdaptationPolicy"):
        from aligngym.estimators.rules import CubatureRule
        aligngym.register_filter("bad-policy", CubatureRule, adaptation=lambda: 3)
    assert "bad-rule" not in aligngym.filter_names()


@pytest.mark.parametrize("kwargs, error, message", [
    ({"episodes": 0}, ValueError, "episodes = 0 must be >= 1"),
    ({"episodes": 2.5}, TypeError, "episodes must be an integer >= 1, got 2.5"),
    ({"seed": -1}, ValueError, "seed = -1 must be >= 0"),
    ({"heading_rms_arcmin": -1.0}, ValueError, "heading_rms_arcmin = -1.0 must be finite"),
    ({"level_rms_arcmin": "1"}, TypeError, "level_rms_arcmin must be a number > 0"),
    ({"filter": 3}, TypeError, "filter must be a non-empty name or path, got 3")])
def test_assert_alignment_checks_its_arguments(kwargs, error, message):
    from aligngym.testing import assert_alignment
    call = {"filter": "ekf", "scenario": "static-large-azimuth", **kwargs}
    with pytest.raises(error) as err:
        assert_alignment(**call)
    assert message in str(err.value)


def no_simulation(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("simulated before the filter was checked")
    monkeypatch.setattr(simulate_module, "simulate", refuse)


def test_a_filter_the_model_cannot_run_is_refused_before_any_simulation(monkeypatch, capsys):
    no_simulation(monkeypatch)
    assert main(["bench", "paper001", "--filters", "imakf", "--episodes", "2"]) == 2
    line = last_line(capsys.readouterr().err)
    assert line.startswith("aligngym: error: filter 'imakf' (improved multiple fading")
    assert "which paper001's model does not give; filters that run here:" in line
    with pytest.raises(ConfigError, match="filter 'imakf'"):
        gym.make("aligngym/Figure8Gps-v1", estimator="imakf")
    with pytest.raises(ConfigError, match="filter 'makf-r'"):
        aligngym.scenarios.evaluate("aligngym/UsvMemsSwing-v1", "makf-r", episodes=1)
    from aligngym.testing import assert_alignment
    with pytest.raises(ConfigError, match="filter 'swakf'"):
        assert_alignment("swakf", "ship-sway-rotary", episodes=1)


# --- 7. a lost filter is lost, diverged or not converged, never passed -------------------------
def test_a_blown_up_sigma_is_lost_or_not_converged():
    """The issue's case: heading sigma 7e7 arcmin and an error of 8270 arcmin (138 deg);
    the 5 x 3 sigma test cannot fire, the 10 deg bound does (lost); a 300 deg sigma
    with a small error is not converged (the filter knows), a healthy 60 deg sigma with
    a 30' error inside the 60' band is converged."""
    error = np.array([[0.1, 0.1, 8270.0], [0.1, 0.1, 1.0], [0.1, 0.1, 30.0]]) * arcmin
    sigma = np.array([[1.0, 1.0, 7e7], [1.0, 1.0, 18000.0], [1.0, 1.0, 3600.0]]) * arcmin
    status, reason = StatusRule().apply(error, sigma, 60 * arcmin, np.zeros(3, bool),
                                        ["", "", ""])
    assert status.tolist() == ["lost", "not converged", "converged"]
    assert reason == ["final error > 10 deg", "attitude sigma > 180 deg", ""]


def test_a_nan_sigma_or_error_counts_as_diverged_and_a_flag_keeps_its_reason():
    """A NaN sigma (a covariance lost to NaN) is diverged whatever the error; a NaN error
    with a finite sigma is not passed as converged either; an episode the filter flagged
    keeps the filter's reason."""
    error = np.array([[0.1, 0.1, 1.0], [0.1, 0.1, np.nan], [0.1, 0.1, 1.0],
                      [0.1, 0.1, 1.0]]) * arcmin
    sigma = np.array([[1.0, 1.0, np.nan], [1.0, 1.0, 3.0], [1.0, 1.0, 3.0],
                      [np.nan, 1.0, 3.0]]) * arcmin
    flagged = np.array([False, False, False, True])
    status, reason = StatusRule().apply(error, sigma, 60 * arcmin, flagged,
                                        ["", "", "", "covariance not positive definite"])
    assert status.tolist() == ["diverged", "diverged", "converged", "diverged"]
    assert reason[0] == reason[1] == "final error or sigma not finite"
    assert reason[2] == "" and reason[3] == "covariance not positive definite"


# --- 8. runs refused before they start ----------------------------------------------------------
def test_a_run_too_large_for_memory_is_refused_first(monkeypatch, capsys):
    monkeypatch.setattr(simulate_module, "available_memory", lambda: 2e9)
    assert main(["simulate", "ship-sway-rotary", "--duration", "86400", "--out", "x.npz"]) == 2
    line = last_line(capsys.readouterr().err)
    assert line == ("aligngym: error: run.duration_s = 86400 s at run.imu_rate_hz = 100 needs "
                    "about 19.0 GB to simulate, more than 50% of the 2.0 GB available; "
                    "shorten the run or lower the IMU rate")


def test_a_car_that_never_drives_is_refused_for_the_odometer_pipeline(tmp_path, capsys):
    from aligngym.scenarios.registry import DATA_DIR
    text = (DATA_DIR / "ring-road-odometer.toml").read_text()
    path = tmp_path / "parked.toml"
    path.write_text(text.replace("speed = 8.0", "speed = 0.0"))
    assert "speed = 0.0" in path.read_text()
    assert main(["bench", "paper000", "--scenario", str(path), "--episodes", "1"]) == 2
    assert ("motion.speed = 0 m/s: paper000's odometer-aided alignment needs the car to "
            "drive") in capsys.readouterr().err


@pytest.mark.parametrize("content", ["[]", '{"settings": {}}', '{"metrics": [1, 2]}',
                                     '{"metrics": {"a": "x"}}', "\xff\xfe"])
def test_a_malformed_baseline_is_one_line(content, tmp_path):
    (tmp_path / "regress_paper002.json").write_text(content, encoding="latin-1")
    with pytest.raises(ConfigError, match="run with --update"):
        regress(["paper002"], directory=tmp_path)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_ctrl_c_dropped_in_a_finaliser_still_stops_the_campaign(tmp_path, monkeypatch):
    """Python drops a KeyboardInterrupt raised inside a finaliser; the CLI's handler
    remembers it and the next finished episode raises it again: exit 130, one line."""
    import gc
    from aligngym.scenarios import interrupts
    from aligngym.scenarios.campaign import executors

    class Finalised:
        def __del__(self):
            interrupts._handler(signal.SIGINT, None)     # the Ctrl-C, inside a __del__

    prepare = executors.PreparedEpisode.save

    def save_and_drop(self, path):
        prepare(self, path)
        Finalised()
        gc.collect()                                     # dropped: "Exception ignored"
    monkeypatch.setattr(executors.PreparedEpisode, "save", save_and_drop)
    out = tmp_path / "c"
    code = main(["bench", "paper002", "--episodes", "3", "--filters", "ekf", "--workers",
                 "1", "--out", str(out)])
    assert code == 130
    assert len(list((out / "episodes").glob("seed_*.npz"))) == 1     # stopped at the next
    interrupts.raise_if_interrupted()          # nothing remembered after the command
