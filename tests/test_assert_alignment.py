"""``assert_alignment`` on every shipped scenario from every start of its experiment, with
short settings and bounds about twice what the filter reaches there (so a filter that
stops converging, or a start that is silently skipped, fails), and its start argument:
the default start, "all", and a start the experiment lacks."""
import pytest

from aligngym.scenarios.experiments import experiment_for, experiment_names
from aligngym.scenarios.registry import scenario_names
from aligngym.testing import AlignmentBoundExceeded, assert_alignment

CASES = {
    # scenario: (filter, episodes, settings, heading bound ', level bound '); measured
    # on seed 0 from the worst start (heading ', level E/N ')
    "figure8-gps": ("lckf", 1, {"fine_duration": 120.0}, 0.5, 0.6),         # 0.04, 0.26
    "figure8-gps-paper": ("rakf", 1, {"fine_duration": 120.0}, 16.0, 0.6),  # 7.8, 0.26
    "figure8-gps-changing": ("lckf", 1, {"fine_duration": 480.0}, 3.0, 2.8),  # 1.51, 1.38
    "ring-road-odometer": ("sgkf", 1, {"fine_duration": 120.0}, 12.0, 0.06),  # 5.2, 0.02
    "ship-sway-rotary": ("kf", 2, {"fine_duration": 120.0}, 20.0, 0.08),    # 9.3, 0.04
    "ship-sway-rotary-paper": ("makf-r", 2, {}, 9.0, 0.4),                  # 4.2, 0.16
    "ship-sway-rotary-changing": ("kf", 2, {}, 0.2, 0.01),                  # 0.096, 0.005
    "ship-waves-rotary": ("kf", 2, {"fine_duration": 120.0}, 3.0, 0.02),    # 1.3, 0.006
    "static-large-azimuth": ("ekf", 1, {"fine_duration": 300.0}, 9.0, 0.25),  # 4.5, 0.12
    "static-large-azimuth-changing": ("ekf", 1, {}, 24.0, 0.35),             # 11.7, 0.16
    "usv-mems-swing": ("stukf", 1, {"fine_duration": 120.0}, 110.0, 4.0),   # 54, 1.8
    "usv-mems-swing-changing": ("stukf", 1, {"fine_duration": 540.0}, 60.0, 4.6),  # 27, 2.4
    "usv-mems-waves": ("stukf", 1, {"fine_duration": 120.0}, 35.0, 15.0),   # 17, 7.3
    "usv-mems-waves-changing": ("stukf", 1, {"fine_duration": 540.0}, 18.0, 6.0),  # 8.3, 2.8
}
"""The paper setups' files (``*-paper``) run their setup's own method: there the classic
filter's trouble is the paper's point (paper 001's uncalibrated misalignment, paper 003's
unmodulated biases)."""


def test_every_shipped_scenario_and_experiment_has_a_case():
    assert sorted(CASES) == scenario_names()
    covered = {experiment_for(name).__class__ for name in CASES}
    shipped = {experiment_for(name).__class__ for name in scenario_names()}
    assert covered == shipped
    assert len({c.__name__ for c in covered}) == len([e for e in experiment_names()
                                                      if e.startswith("paper")])


RUN_ORDER = sorted(CASES, key=lambda name: name != "figure8-gps-changing")
"""The cases in name order but figure8-gps-changing first: the car's run on its smooth
road is one run for every seed, and a shorter one is the start of a longer one
(``world_truth.shared_motion``); its 480 s fine run taken first serves figure8-gps and
figure8-gps-paper from the truth cache instead of a second, shorter MuJoCo run."""


@pytest.mark.parametrize("scenario", RUN_ORDER)
def test_every_start_of_every_shipped_scenario_within_its_bounds(scenario):
    name, episodes, settings, heading, level = CASES[scenario]
    starts = experiment_for(scenario, **settings).starts
    measured = assert_alignment(name, scenario, episodes=episodes, seed=0, start="all",
                                heading_rms_arcmin=heading, level_rms_arcmin=level,
                                **settings)
    assert list(measured) == list(starts)
    for start, errors in measured.items():
        assert errors["start"] == start and errors["diverged"] == 0
        # the bounds are not so loose that any filter passes: within 2.2x of the value
        assert errors["heading_rms_arcmin"] > heading / 40
        assert max(errors["level_rms_arcmin"]) > level / 40


def test_the_default_start_is_the_first_and_a_start_is_checked_by_name():
    settings = {"fine_duration": 120.0}
    every = assert_alignment("kf", "ship-sway-rotary", episodes=2, start="all", **settings)
    assert list(every) == ["mean", "max"]
    assert every["mean"] != every["max"]                   # two starts, two runs
    assert assert_alignment("kf", "ship-sway-rotary", episodes=2, **settings) == every["mean"]
    assert assert_alignment("kf", "ship-sway-rotary", episodes=2, start="max",
                            **settings) == every["max"]
    with pytest.raises(ValueError, match=r"start = 'big' is not a start of paper003; "
                                         r"valid: mean, max, all$"):
        assert_alignment("kf", "ship-sway-rotary", start="big")


def test_a_failure_names_only_the_start_beyond_the_bound():
    with pytest.raises(AlignmentBoundExceeded) as error:
        assert_alignment("kf", "ship-sway-rotary", episodes=2, start="all",
                         heading_rms_arcmin=9.0, fine_duration=120.0)
    text = str(error.value)                      # mean start 8.4', max start 9.3'
    assert "from the max start" in text and "mean start" not in text
    assert "heading RMS 9.304' > 9'" in text


def test_the_table_keeps_its_columns_apart_at_any_size():
    """A filter lost by 179 deg with a 6-digit seed: every number its own column."""
    from types import SimpleNamespace

    import numpy as np

    from aligngym.models.units import arcmin
    from aligngym.testing import _check_run
    error = np.array([[[0.1, -2.0, -10745.089]], [[-12345.678, 0.5, 3.0]]]) * arcmin
    run = SimpleNamespace(error_n=error, status=np.array(["lost", "not converged"]),
                          reason=["final error > 10 deg", "final error > the 60' band"])
    measured, table = _check_run(run, "ekf", "static-large-azimuth", "large-azimuth", 2,
                                 0, [123456, 2], 10.0, None)
    assert (measured["lost"], measured["not_converged"], measured["diverged"]) == (1, 1, 0)
    assert "1 of 2 episodes lost" in table.splitlines()[0]
    rows = [line.split() for line in table.splitlines()[2:]]
    assert rows[0][:5] == ["123456", "0.100", "-2.000", "-10745.089", "lost:"]
    assert rows[1][:5] == ["2", "-12345.678", "0.500", "3.000", "not"]
    assert rows[2][0] == "RMS" and len(rows[2]) == 4


def test_paper000_runs_only_the_start_asked_for():
    """paper 000 declares its starts as a setting: the check runs the chosen one alone."""
    one = assert_alignment("sgkf", "ring-road-odometer", episodes=1, start="large",
                           fine_duration=120.0)
    assert one["start"] == "large"
