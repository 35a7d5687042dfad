"""Property-based tests over command-line options (issue: fuzzed options): valid commands
with one to three options mutated (negative, zero, huge, NaN/inf, non-numbers, empty,
unknown choices, odd paths and filter lists, options of another paper, flags added).
Every case either passes validation (the run is stopped where the work would start:
the simulation, the fidelity run, or the campaign's episode preparation) or is refused
with exit status 2 and an error line naming what is wrong; never a traceback."""
import contextlib
import functools
import io

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import aligngym.scenarios.campaign
import aligngym.scenarios.fidelity
import aligngym.scenarios.simulate
from aligngym import scenarios
from aligngym.scenarios import cli
from aligngym.scenarios.cli import main


class Accepted(Exception):
    """Validation passed: the work would start here."""


def stop(*args, **kwargs):
    raise Accepted


BASE = {
    "simulate": ["simulate", "ship-sway-rotary", "--duration", "1", "--out", "x.npz"],
    "fidelity": ["fidelity", "static-large-azimuth", "--duration", "1"],
    "bench": ["bench", "paper002", "--episodes", "2"],
}
OPTIONS = {
    "simulate": ["--duration", "--seed", "--imu-rate", "--out", "scenario"],
    "fidelity": ["--duration", "--seed", "--imu-rate", "scenario"],
    "bench": ["--episodes", "--seed", "--filters", "--scenario", "--outage", "--workers",
              "--disturbance", "--coarse", "--heading-point", "--swing", "--motion",
              "--misalignment", "--case", "--setup", "--out", "--json", "--executor",
              "--address", "paper"],
}
FLAGS = {"simulate": ["--ideal"], "fidelity": [], "bench": ["--resume", "--force"]}
VALUES = st.one_of(
    st.sampled_from(["0", "-1", "-0.5", "1e400", "1e30", "nan", "inf", "-inf", "", "abc",
                     "1", "2", "0.5", "100", "2000", "7.3", "mild", "wild", "waves",
                     "ekf", "ekf,,ukf", "nope", "ukf,sghkf-99", ":", "os:path",
                     "ring-road-odometer", "usv-mems-waves", "ship-waves-rotary",
                     "missing.toml", "/dev/null/dir/x.npz", "out.npz", "out.txt",
                     "paper003", "paper004", "paper009", "ray", "local", "auto"]),
    st.integers(-10 ** 6, 10 ** 6).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=6))


PLAUSIBLE = {   # values that pass argparse, so that the commands' own checks are reached
    "--filters": ["ekf", "ukf,ckf", "stukf", "imakf", "sghkf-2", "swakf", "kf-sway",
                  "ekf,nope", "ghkf-3", ""],
    "--scenario": ["ship-sway-rotary", "figure8-gps", "usv-mems-waves",
                   "static-large-azimuth", "ring-road-odometer", "missing.toml", "x"],
    "--outage": ["0", "30", "1e9"], "--workers": ["1", "3"], "--episodes": ["1", "3"],
    "--seed": ["0", "5"], "--swing": ["mild", "all"], "--motion": ["waves"],
    "--case": ["turntable", "consistency"], "--coarse": ["moving"],
    "--disturbance": ["slip"], "--heading-point": ["rear-axle"], "--setup": ["paper"],
    "--misalignment": ["coarse", "small"], "--executor": ["local", "ray"],
    "--address": ["auto"], "--out": ["out", "/dev/null/dir", "x.npz"],
    "--json": ["s.json", "/dev/null/s.json", "out"],
    "paper": ["paper000", "paper001", "paper003", "paper004"],
    "--duration": ["0.5", "2", "86400", "1e5"], "--imu-rate": ["100", "250", "7", "2000"],
    "scenario": ["usv-mems-swing", "figure8-gps", "static-large-azimuth"],
}


@st.composite
def mutated_command(draw):
    command = draw(st.sampled_from(sorted(BASE)))
    argv = list(BASE[command])
    for _ in range(draw(st.integers(1, 3))):
        option = draw(st.sampled_from(OPTIONS[command]))
        value = (draw(st.sampled_from(PLAUSIBLE[option]))
                 if option in PLAUSIBLE and draw(st.booleans()) else draw(VALUES))
        if option in ("scenario", "paper"):
            argv[1] = value
        elif option in argv:
            argv[argv.index(option) + 1] = value
        else:
            argv += [option, value]
    if FLAGS[command] and draw(st.booleans()):
        argv.append(draw(st.sampled_from(FLAGS[command])))
    return argv


@pytest.fixture
def stopped(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(scenarios.simulate, "simulate", stop)
    monkeypatch.setattr(scenarios.fidelity, "fidelity_errors", stop)
    monkeypatch.setattr(scenarios.campaign.engine, "prepare_all", stop)
    # The parser main builds for every call, built once per value of what it is built
    # from (build_parser's arguments: --help's filter list, the experiment bench names)
    # and reused: the same parser (argparse keeps nothing of a parse; 3000 cases gave the
    # same status and messages either way), where building it 1000 times took half of
    # the test's time. Each case's parse and validation, what is under test, run as
    # before.
    monkeypatch.setattr(cli, "build_parser", functools.lru_cache(maxsize=None)(
        cli.build_parser))


@settings(max_examples=1000, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(argv=mutated_command())
def test_fuzzed_options_are_accepted_or_refused_in_one_line(stopped, argv):
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
    except Accepted:
        return
    except SystemExit as exc:            # argparse: usage, then its error line
        code = exc.code
    text = err.getvalue()
    assert code == 2, (argv, code, text)
    assert "Traceback" not in text
    last = text.strip().splitlines()[-1]
    assert "error:" in last and len(last) < 400, (argv, text)
