"""The prescribed sway's sea state within an episode (issue 44 item 1): ``motion.sway_scale``
and its [[schedule]] changes, reached by smooth ramps. The motion's rates and
accelerations against finite differences of its angles and positions across the ramps,
the amplitudes before and after, the strapdown on its ideal IMU data against its truth
(SPEC section 3, 10x tighter), a change to the same value changing no number, the filter
tuned for the file's sea, and bad entries as one line."""
import re

import numpy as np
import pytest

from aligngym.models.units import arcsec
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.experiments.paper003 import sway_peak_velocity
from aligngym.scenarios.registry import DATA_DIR
from aligngym.scenarios.simulate import simulate
from aligngym.scenarios.worlds import world_of
from scenario_files import shipped_with

SHIP = "ship-sway-rotary"
SQUALL = """
[[schedule]]
time_s = 20.0
ramp_s = 10.0
motion.sway_scale = 2.5

[[schedule]]
time_s = 50.0
ramp_s = 5.0
motion.sway_scale = 0.5
"""


@pytest.fixture(scope="module")
def squall(tmp_path_factory):
    config = load_scenario(shipped_with(tmp_path_factory.mktemp("sway"), SHIP, 80.0, SQUALL))
    return config, world_of(config).episode_motion(config, np.random.default_rng(3))


def test_rates_and_accelerations_are_the_derivatives_across_the_ramps(squall):
    """Central differences (h = 1 ms) of the Euler angles and the sway centre's position
    and velocity match the analytic rates and accelerations to 1e-6 of their scale,
    including on the ramps (20-30 s, 50-55 s), where the sway scale's own derivatives
    enter."""
    _, motion = squall
    t = np.linspace(0.5, 79.5, 20001)
    h = 1e-3
    angle, rate, accel = motion.euler(t)
    plus, minus = motion.euler(t + h), motion.euler(t - h)
    np.testing.assert_allclose((plus[0] - minus[0]) / (2 * h), rate,
                               atol=1e-6 * np.abs(rate).max())
    np.testing.assert_allclose((plus[1] - minus[1]) / (2 * h), accel,
                               atol=1e-6 * np.abs(accel).max())
    r, v, a = motion.sway_centre(t)
    rp, vp, _ = motion.sway_centre(t + h)
    rm, vm, _ = motion.sway_centre(t - h)
    np.testing.assert_allclose((rp - rm) / (2 * h), v, atol=1e-6 * np.abs(v).max())
    np.testing.assert_allclose((vp - vm) / (2 * h), a, atol=1e-6 * np.abs(a).max())
    k, dk, ddk = motion.sway_scale_at(np.array([19.0, 25.0, 31.0, 52.5, 60.0]))
    np.testing.assert_allclose(k, [1.0, 1.75, 2.5, 1.5, 0.5])
    assert dk[0] == dk[2] == dk[4] == 0.0 and ddk[0] == ddk[2] == 0.0
    assert dk[1] == pytest.approx(1.5 * 140 / 64 / 10.0)    # S'(1/2) = 140 / 64


def test_the_amplitudes_follow_the_sea(squall):
    """The heave and the roll reach k x their file's amplitude in each calm stretch."""
    config, motion = squall
    t = np.arange(0.0, 80.0, 0.01)
    angle, _, _ = motion.euler(t)
    heave = motion.sway_centre(t)[0][:, 2]
    for (a, b), k in (((0, 20), 1.0), ((31, 50), 2.5), ((56, 80), 0.5)):
        inside = (t >= a) & (t < b)
        assert np.abs(heave[inside]).max() == pytest.approx(
            k * config.motion.linear_amplitude[2], rel=2e-3)
        assert np.abs(angle[inside, 1]).max() == pytest.approx(
            k * config.motion.roll_amplitude, rel=2e-3)


def test_the_strapdown_tracks_the_truth_through_the_squall(tmp_path):
    """SPEC section 3 on the scheduled ship (the sea 0.4x, a squall to 1.5x, 0.4x again,
    as the shipped ship-sway-rotary-changing, compressed to 200 s): 10x tighter than 1
    arcsec, 5 mm/s, 1 m."""
    from aligngym.scenarios.fidelity import fidelity_errors
    text = (DATA_DIR / "ship-sway-rotary-changing.toml").read_text()
    text = re.sub(r"duration_s = [0-9.]+", "duration_s = 200.0", text)
    for old, new in (("300.0", "40.0"), ("540.0", "140.0")):
        text = text.replace(f"time_s = {old}", f"time_s = {new}")
    path = tmp_path / "squall.toml"
    path.write_text(text)
    config = load_scenario(str(path))
    assert config.schedule.boundaries() == (40.0, 100.0, 140.0, 200.0)
    err = fidelity_errors(config, seed=1)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def test_a_change_to_the_same_scale_changes_no_number(tmp_path):
    same = "\n[[schedule]]\ntime_s = 10.0\nramp_s = 5.0\nmotion.sway_scale = 1.0\n"
    plain = simulate(load_scenario(shipped_with(tmp_path, SHIP, 30.0)), seed=3)
    config = load_scenario(shipped_with(tmp_path, SHIP, 30.0, same))
    assert config.schedule
    scheduled = simulate(config, seed=3)
    for name, value in plain.arrays().items():
        np.testing.assert_array_equal(scheduled.arrays()[name], value, err_msg=name)


def test_the_filter_is_tuned_for_the_files_sea_not_the_schedule(tmp_path):
    """Paper 003's R comes from the sway peak at the file's sway_scale (0.4x: 0.4x the
    peak); the schedule's squall is not known to it."""
    plain = load_scenario("ship-sway-rotary")
    changing = load_scenario("ship-sway-rotary-changing")
    assert changing.motion.sway_scale == 0.4 and changing.schedule
    np.testing.assert_allclose(sway_peak_velocity(changing.motion),
                               0.4 * sway_peak_velocity(plain.motion), rtol=1e-15)


@pytest.mark.parametrize("extra, scale, message", [
    ("\n[[schedule]]\ntime_s = 10.0\nmotion.sway_scale = 2.0\n", "",
     "schedule[0].ramp_s = 0 s must be > 0 for motion.sway_scale"),
    ("\n[[schedule]]\ntime_s = 10.0\nramp_s = 2.0\nmotion.sway_scale = 12.0\n", "",
     "schedule[0].motion.sway_scale = 12 is out of range [0, 10]"),
    ("", "sway_scale = -1.0\n", "motion.sway_scale = -1 is out of range [0, 10]"),
    ("\n[[schedule]]\ntime_s = 10.0\nramp_s = 2.0\nmotion.sway_scal = 2.0\n", "",
     "schedule[0].motion.sway_scal is not a parameter a schedule may change; did you "
     "mean sway_scale?"),
])
def test_a_bad_sway_entry_is_one_line_naming_it(tmp_path, extra, scale, message):
    with pytest.raises(ConfigError) as info:
        load_scenario(shipped_with(tmp_path, SHIP, 30.0, extra, motion=scale))
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_world_without_a_sea_refuses_it(tmp_path):
    with pytest.raises(ConfigError, match="schedule.0. table = 'motion' is unknown"):
        load_scenario(shipped_with(tmp_path, "static-large-azimuth", 30.0,
                                   "\n[[schedule]]\ntime_s = 10.0\nramp_s = 2.0\n"
                                   "motion.sway_scale = 2.0\n"))


def test_a_shorter_run_is_the_longer_ones_beginning(tmp_path):
    """A run shorter than the file's (an experiment's, an env's) reaches only the entries
    before its end, and a ramp still going at its end is kept: its truth and ideal IMU
    data are the longer run's first part (here the squall's ramp, 20-30 s, cut at 25 s;
    the sensors' random draws depend on the run's length either way)."""
    config = load_scenario(shipped_with(tmp_path, SHIP, 80.0, SQUALL))
    short = config.with_options(duration=25.0)
    assert [e.time for e in short.schedule.entries] == [20.0]
    assert not config.with_options(duration=10.0).schedule
    long_, cut = simulate(config, seed=4, ideal=True), simulate(short, seed=4, ideal=True)
    n = cut.dtheta.shape[0]
    np.testing.assert_array_equal(cut.truth.h, long_.truth.h[:n + 1])
    np.testing.assert_array_equal(cut.dv, long_.dv[:n])
